"""Gravity deposition of polydisperse disks in a 2D box (Perez's soft-particle model:
linear spring-dashpot with repulsive-only force, restitution 0.95, Cundall-Strack
friction): loose lattice with random velocities, settle, print, draw.

    python examples/deposition_2d.py [--grains 1000] [--out runs/deposition_2d]
"""
import json

import numpy as np

import graindyn as gd
from graindyn.protocols.prepare import BoxRegion, lattice_insertion, settle

import example_args  # examples/example_args.py, next to this script


def main():
    args, out, rng = example_args.parse(__doc__, "deposition_2d")

    d_ave, spread = 1e-3, 0.2e-3                                   # [m]
    width = 40 * d_ave
    radii = gd.sample_radii(args.grains, "uniform", rng, d_min=d_ave - spread,
                            d_max=d_ave + spread)
    layers = int(np.ceil(args.grains / int(width / (1.3 * (d_ave + spread)))))
    height = (layers + 2) * 1.1 * (d_ave + spread)
    positions, velocities = lattice_insertion(radii, BoxRegion((0, 0), (width, height)), rng,
                                              dim=2, gap=0.1, speed=0.05)
    state = gd.State.create(positions, radii, 1.0, dim=2, velocities=velocities)
    kn = 1e3 * np.pi * (0.5 * d_ave) ** 2 * 1.0 * 9.81 / (1e-3 * d_ave)  # 1e-3 d overlap per 1e3 weights
    disk = gd.Material("disk", density=1.0, restitution=0.95, kn=kn, kt=kn / 3,
                       friction_sliding=0.5, tangential_damping=1.0 / 3)
    model = gd.ContactModel("hooke", "linear", "cundall_strack")
    walls = gd.box((0, 0), (width, 2 * height), open_top=True, dim=2)
    sim = gd.Simulation(state, [disk], model, walls=walls, gravity=(0, -9.81, 0))
    print(f"{args.grains} disks, kn = {kn:.3g} N/m, dt = {sim.dt:.3g} s "
          f"({sim.dt_report['fraction']:.3f} of the contact time)")
    report = settle(sim, max_time=3.0, bottom_wall="ylo", cross_section=width)
    print(json.dumps({k: v for k, v in report.items() if k != "energy_J"}, indent=1))
    (out / "report.json").write_text(json.dumps(report, indent=1))

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import EllipseCollection

    fig, ax = plt.subplots(figsize=(6, 6))
    p = state.positions
    d = 2e3 * state.radii
    ax.add_collection(EllipseCollection(d, d, 0, units="xy", offsets=p[:, :2] * 1e3,
                                        offset_transform=ax.transData, facecolors="tan",
                                        edgecolors="k", linewidths=0.2))
    ax.set(xlim=(0, width * 1e3), ylim=(0, report["bed_height_m"] * 1.1e3), aspect="equal",
           xlabel="x [mm]", ylabel="y [mm]", title=f"settled 2D bed, phi = "
           f"{report.get('packing_fraction_core', report['packing_fraction']):.3f}")
    fig.savefig(out / "deposition_2d.png", dpi=120)
    print(f"figure: {out / 'deposition_2d.png'}")


if __name__ == "__main__":
    main()
