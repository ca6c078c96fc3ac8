"""Gravity deposition of polydisperse spheres in a box (3D): insert at random, settle
until E_kin/E_pot <= 1e-6 (Karrech et al.), print the settled sample, draw a figure.

    python examples/deposition_3d.py [--grains 1000] [--out runs/deposition_3d]
"""
import json
import time

import numpy as np

import graindyn as gd
from graindyn.analysis.energy import energy_budget
from graindyn.protocols.prepare import BoxRegion, random_insertion, settle

import example_args  # examples/example_args.py, next to this script


def main():
    args, out, rng = example_args.parse(__doc__, "deposition_3d")

    d_min, d_max, side = 0.85e-3, 1.15e-3, 10e-3               # [m]
    radii = gd.sample_radii(args.grains, "uniform", rng, d_min=d_min, d_max=d_max)
    volume = np.sum(4 / 3 * np.pi * radii**3)
    height = volume / (0.2 * side * side)                         # insert at solid fraction 0.2
    positions, radii = random_insertion(radii, BoxRegion((0, 0, 0), (side, side, height)), rng)
    state = gd.State.create(positions, radii, 2650.0)
    grain = gd.Material("quartz", density=2650.0, youngs_modulus=1e8, poisson_ratio=0.3,
                        restitution=0.9, friction_sliding=0.5, tangential_damping=1.0)
    model = gd.ContactModel("hertz", "tsuji", "mindlin")
    walls = gd.box((0, 0, 0), (side, side, 2 * height), open_top=True)
    sim = gd.Simulation(state, [grain], model, walls=walls)
    print(f"{args.grains} grains, dt = {sim.dt:.3g} s = {sim.dt_report['fraction']:.2f} of the "
          f"Rayleigh time {sim.dt_report['critical_time_s']:.3g} s")

    series = []

    def record(s):
        e = energy_budget(s)
        series.append((s.time, e["kinetic"] + e["rotational"], s.walls.normal_force(4)))

    t0 = time.perf_counter()
    report = settle(sim, max_time=1.0, bottom_wall="zlo", cross_section=side * side,
                    every=[(gd.Periodic(time=2e-3), record)])
    wall = time.perf_counter() - t0
    report["wall_time_s"] = wall
    report["particle_steps_per_s"] = args.grains * sim.step / wall
    print(json.dumps({k: v for k, v in report.items() if k != "energy_J"}, indent=1))
    (out / "report.json").write_text(json.dumps(report, indent=1))

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t, ek, fw = np.array(series).T
    fig, ax = plt.subplots(1, 3, figsize=(13, 4))
    from matplotlib.collections import EllipseCollection

    p = state.positions
    cut = np.abs(p[:, 1] - 0.5 * side) < state.radii          # grains cut by y = side/2
    half = np.sqrt(state.radii[cut] ** 2 - (p[cut, 1] - 0.5 * side) ** 2)
    ax[0].add_collection(EllipseCollection(2e3 * half, 2e3 * half, 0, units="xy",
                                           offsets=p[cut][:, [0, 2]] * 1e3,
                                           offset_transform=ax[0].transData,
                                           facecolors="tan", edgecolors="k", linewidths=0.3))
    ax[0].set(xlim=(0, side * 1e3), ylim=(0, report["bed_height_m"] * 1.1e3), aspect="equal",
              xlabel="x [mm]", ylabel="z [mm]", title="settled bed, section y = L/2")
    ax[1].semilogy(t, ek)
    ax[1].set(xlabel="t [s]", ylabel="kinetic energy [J]")
    ax[2].plot(t, fw / report["total_weight_N"])
    ax[2].set(xlabel="t [s]", ylabel="bottom force / weight")
    fig.tight_layout()
    fig.savefig(out / "deposition_3d.png", dpi=120)
    print(f"figure: {out / 'deposition_3d.png'}")


if __name__ == "__main__":
    main()
