"""graindyn and LAMMPS side by side in 2D, on a settled bed of the silo's size.

    python benchmarks/lammps_silo_2d.py [--grains 2000] [--steps 20000] [--repeats 2]
                                        [--threads 1] [--work DIR]

The bed: the disks of examples/silo.toml (d = 5 mm +- 0.5 mm, areal density 8 kg/m^2)
in its 15 cm wide box, settled once by graindyn (untimed) with the law both codes run:
a linear spring kn = 4e3 N/m with a normal dashpot (restitution 0.9 for the mean pair:
LAMMPS `gran/hooke/history` gamma_n; graindyn `hooke` + `linear` damping, the same
dashpot for every pair of the mean mass), a Coulomb-capped tangential spring
kt = 2 kn / 7, mu = 0.5, no tangential dashpot (LAMMPS's history spring; graindyn
`cundall_strack`), walls with the same law (LAMMPS `fix wall/gran`), g = 9.81 m/s^2,
dt = 4.4e-6 s (0.01 t_coll), neighbour skin 0.5 mm checked every step.  LAMMPS runs
`dimension 2` with `fix enforce2d`; both read the same state, run 1000 untimed and
STEPS timed steps (graindyn on --threads numba threads, LAMMPS on as many MPI ranks),
and the median of the repeats is printed with the contacts per disk (they must agree,
else the beds differ) and the ratio, with the median and range of the ratios of each
repeat's two runs, which ran one after the other (on a shared machine they see the same
load more nearly than the medians do).  Needs `lmp` and, for more than one rank,
`mpirun` (apt-get install lammps); work files go to --work (default
$TMPDIR/graindyn_silo_bench).
"""
import argparse
import math
import os
import pathlib
import re
import statistics
import subprocess
import tempfile
import time

import numpy as np

KN, RESTITUTION, MU, DT, SKIN, DENSITY, WIDTH = 4e3, 0.9, 0.5, 4.4e-6, 5e-4, 8.0, 0.15
KT = 2.0 * KN / 7.0


def gamma_n(mass_eff):
    """LAMMPS gran/hooke gamma_n [1/s] giving restitution e to a pair of reduced mass
    mass_eff: f = kn delta - m_eff gamma_n v_n, e = exp(-gamma_n t_c / 2)."""
    ln = -math.log(RESTITUTION)
    omega = math.sqrt(KN / mass_eff)
    return 2.0 * ln * omega / math.sqrt(math.pi**2 + ln**2)


def simulation(state, threads=1):
    """The graindyn Simulation of ``state`` with the benchmark's physics."""
    import graindyn as gd

    disk = gd.Material("disk", density=DENSITY, kn=KN, kt=KT, restitution=RESTITUTION,
                       friction_sliding=MU, friction_static=MU)
    model = gd.ContactModel("hooke", "linear", "cundall_strack", limit_damping=False)
    walls = [gd.Plane((0, 0, 0), (1, 0, 0), name="xlo"),
             gd.Plane((WIDTH, 0, 0), (-1, 0, 0), name="xhi"),
             gd.Plane((0, 0, 0), (0, 1, 0), name="floor")]
    return gd.Simulation(state, [disk], model, walls=walls, gravity=(0, -9.81, 0), dt=DT,
                         skin=SKIN, check_interval=1000, orientations=False)


def settled_bed(n, work):
    """x y r of n disks settled in the box (made once, kept in ``work``)."""
    path = work / f"bed_{n}.txt"
    if path.exists():
        return np.loadtxt(path)
    import graindyn as gd
    from graindyn.protocols.prepare import BoxRegion, lattice_insertion

    rng = np.random.default_rng(1)
    radii = rng.uniform(0.00225, 0.00275, n)
    positions, velocities = lattice_insertion(radii, BoxRegion((0.0, 0.0), (WIDTH, 2.0)),
                                              rng, dim=2, gap=0.05, speed=0.05)
    state = gd.State.create(positions, radii, DENSITY, dim=2, velocities=velocities)
    sim = simulation(state)
    sim.run(time=1.5, until=gd.MaxSpeedBelow(2e-3))
    s = sim.state
    np.savetxt(path, np.column_stack([s.positions[:, 0], s.positions[:, 1], s.radii]))
    return np.loadtxt(path)


def bed_simulation(bed):
    """The Simulation of the bed ``bed`` (x y r rows), its disks in cell order."""
    import graindyn as gd

    state = gd.State.create(np.column_stack([bed[:, :2], np.zeros(len(bed))]), bed[:, 2],
                            DENSITY, dim=2)
    return simulation(state.reordered(
        gd.cell_order(state.positions, 2 * state.radii.max() + SKIN)))


def run_graindyn(bed, steps, threads):
    import numba

    import graindyn  # noqa: F401  (chooses numba's threading layer before threads start)

    numba.set_num_threads(threads)
    sim = bed_simulation(bed)
    state = sim.state
    sim.run(steps=1000)
    t = time.perf_counter()
    sim.run(steps=steps)
    wall = time.perf_counter() - t
    return wall, 2 * sim.contacts().i.size / state.n


LAMMPS_INPUT = """
dimension 2
units si
atom_style sphere
boundary f f p
newton off
comm_modify vel yes
read_data {data}
set group all density/disc {density}
pair_style gran/hooke/history {kn} {kt} {gn} 0.0 {mu} 0
pair_coeff * *
neighbor {skin} bin
neigh_modify delay 0 every 1 check yes
fix 1 all nve/sphere disc
fix 2 all gravity 9.81 vector 0 -1 0
fix 3 all enforce2d
fix xw all wall/gran hooke/history {kn} {kt} {gn} 0.0 {mu} 0 xplane 0.0 {width}
fix yw all wall/gran hooke/history {kn} {kt} {gn} 0.0 {mu} 0 yplane 0.0 NULL
timestep {dt}
compute c all contact/atom
compute z all reduce sum c_c
thermo_style custom step c_z
thermo {steps}
run 1000
run {steps}
"""


def mpi_prefix(ranks):
    """mpirun for ``ranks`` LAMMPS ranks (none for one)."""
    if ranks <= 1:
        return []
    root = ["--allow-run-as-root"] if hasattr(os, "geteuid") and os.geteuid() == 0 else []
    return ["mpirun", *root, "-np", str(ranks)]


def run_lammps(bed, steps, work, ranks=1):
    n = len(bed)
    data = work / f"bed_{n}.data"
    top = float(np.max(bed[:, 1] + bed[:, 2])) + 0.05
    lines = ["LAMMPS 2D silo bed", "", f"{n} atoms", "1 atom types", "",
             f"0.0 {WIDTH} xlo xhi", f"0.0 {top} ylo yhi", "-0.005 0.005 zlo zhi", "",
             "Atoms # sphere", ""]
    lines += [f"{k + 1} 1 {2 * float(r)!r} {DENSITY} {float(x)!r} {float(y)!r} 0.0"
              for k, (x, y, r) in enumerate(bed)]
    data.write_text("\n".join(lines) + "\n")
    mass = DENSITY * math.pi * float(np.mean(bed[:, 2])) ** 2
    script = work / "silo_2d.in"
    script.write_text(LAMMPS_INPUT.format(data=data, density=DENSITY, kn=KN, kt=KT,
                                          gn=gamma_n(0.5 * mass), mu=MU, skin=SKIN,
                                          width=WIDTH, dt=DT, steps=steps))
    out = subprocess.run([*mpi_prefix(ranks), "lmp", "-in", str(script),
                          "-log", str(work / "log.lammps")],
                         capture_output=True, text=True, check=True, cwd=work).stdout
    loops = re.findall(r"Loop time of ([0-9.eE+-]+) on", out)
    z = re.findall(rf"^\s*{1000 + steps}\s+([0-9.eE+-]+)", out, re.M)
    return float(loops[-1]), float(z[-1]) / n if z else float("nan")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--grains", type=int, default=2000)
    parser.add_argument("--steps", type=int, default=20000)
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--work", default=os.path.join(tempfile.gettempdir(),
                                                       "graindyn_silo_bench"))
    args = parser.parse_args()
    work = pathlib.Path(args.work)
    work.mkdir(parents=True, exist_ok=True)
    bed = settled_bed(args.grains, work)
    ours, theirs = [], []
    for _ in range(args.repeats):
        ours.append(run_graindyn(bed, args.steps, args.threads))
        theirs.append(run_lammps(bed, args.steps, work, args.threads))
        print(f"graindyn {ours[-1][0]:.3f} s (zpp {ours[-1][1]:.3f}), LAMMPS "
              f"{theirs[-1][0]:.3f} s (zpp {theirs[-1][1]:.3f})", flush=True)
    g = statistics.median(w for w, _ in ours)
    lam = statistics.median(w for w, _ in theirs)
    n, steps = args.grains, args.steps
    print(f"{n} disks, {steps} steps, {args.threads} thread(s): graindyn {g:.3f} s "
          f"({n * steps / g:.3e} disk-steps/s), LAMMPS {lam:.3f} s "
          f"({n * steps / lam:.3e}), LAMMPS / graindyn = {lam / g:.2f}")
    ratios = [l / o for (o, _), (l, _) in zip(ours, theirs)]
    print(f"LAMMPS / graindyn repeat by repeat: median {statistics.median(ratios):.2f}, "
          f"{min(ratios):.2f} to {max(ratios):.2f}")


if __name__ == "__main__":
    main()
