"""graindyn side of the LAMMPS benchmark (../shared/bench/run_all.py --custom ...).

    python benchmarks/lammps_bed.py STATE CYL SIZE E e DT SKIN WARM STEPS THREADS [LAWS]
                                    [--orientations] [--file-order] [--layer NAME]

Loads the settled bed STATE (x y z r per line, SI), builds the same container (CYL 0:
box [0, SIZE]^2 with a floor at z = 0 and an open top; CYL 1: cylinder of radius SIZE
about the z axis with a floor at z = 0), the same physics as lmp_bench.in (Hertz with
E and nu = 0.3, Mindlin tangential spring, tangential damping ratio 1, mu = 0.5, Tsuji
damping from restitution e, no damping limit, rho = 2650, g = 9.81), runs WARM untimed
and STEPS timed steps on THREADS threads, and prints `wall <s>`, `zpp <contacts per
grain>`, particle-steps/s and peak memory.  LAMMPS's granular atoms carry no
orientation, so the grains' orientations are not turned (Simulation(orientations=False),
the same trajectory) unless --orientations is given (graindyn's default).
The grains are put in cell order on loading (graindyn.cell_order, cells of the
neighbour cutoff 2 R_max + SKIN), as LAMMPS sorts its atoms into bins (`atom_modify
sort`, on by default); --file-order keeps the order of STATE.  --layer NAME starts numba's threads on that
threading layer (omp, workqueue or tbb) before graindyn is imported, so that a layer
graindyn would not choose (TBB) can be timed too; graindyn's own choice otherwise.

LAWS (optional, not used by run_all.py) swaps the contact model, to time another law on
the same bed: "normal,damping,tangential[,rolling[,twisting]]".  The linear and
Walton-Braun springs then get kn = 2e3 N/m (near the Hertz stiffness of this bed),
rolling and twisting coefficients 0.1, and EPSD springs of similar stiffness.
"""
import resource
import sys
import time

import numpy as np


def bed(state_file, cyl, size, young, rest, dt, skin, laws=("hertz", "tsuji", "mindlin"),
        orientations=False, sort=True):
    """The Simulation of the benchmark bed (arguments as on the command line); with
    ``sort``, its grains in cell order (cells of the neighbour cutoff)."""
    import graindyn as gd

    data = np.loadtxt(state_file, ndmin=2)
    size = float(size)
    state = gd.State.create(data[:, :3], data[:, 3], 2650.0)
    if sort:
        state = state.reordered(gd.cell_order(state.positions,
                                              2.0 * state.radii.max() + float(skin)))
    grain = gd.Material("bed", density=2650.0, youngs_modulus=float(young), poisson_ratio=0.3,
                        restitution=float(rest), friction_sliding=0.5, tangential_damping=1.0,
                        kn=2e3, kt=2e3 / 3, alpha_n=0.3, alpha_t=0.3, gamma_n=1e4,
                        friction_rolling=0.1, friction_twisting=0.1, rolling_stiffness=1e3,
                        twisting_stiffness=1e-5, gamma_nt=100.0)
    model = gd.ContactModel(*laws, limit_damping=False)
    floor = gd.Plane((0, 0, 0), (0, 0, 1), name="floor")
    if int(cyl):
        walls = [gd.Cylinder((0, 0, 0), (0, 0, 1), size), floor]
    else:
        walls = [gd.Plane((0, 0, 0), (1, 0, 0)), gd.Plane((size, 0, 0), (-1, 0, 0)),
                 gd.Plane((0, 0, 0), (0, 1, 0)), gd.Plane((0, size, 0), (0, -1, 0)), floor]
    return gd.Simulation(state, [grain], model, walls=walls, dt=float(dt), skin=float(skin),
                         check_interval=1000, orientations=orientations)


def start_threads(layer):
    """numba's threads started on ``layer``, before graindyn chooses one."""
    import numba
    from numba.np.ufunc import parallel

    numba.config.THREADING_LAYER = layer
    parallel._launch_threads()
    if numba.threading_layer() != layer:
        sys.exit(f"threading layer {layer} did not start ({numba.threading_layer()})")


def main(argv):
    orientations = "--orientations" in argv
    sort = "--file-order" not in argv
    argv = [a for a in argv if a not in ("--orientations", "--file-order")]
    if "--layer" in argv:
        k = argv.index("--layer")
        start_threads(argv[k + 1])
        del argv[k:k + 2]
    if len(argv) not in (10, 11):
        sys.exit(__doc__)
    state_file, cyl, size, young, rest, dt, skin, warm, steps, threads = argv[:10]
    laws = argv[10].split(",") if len(argv) == 11 else ["hertz", "tsuji", "mindlin"]
    import numba

    import graindyn  # noqa: F401  (chooses numba's threading layer before threads start)
    from graindyn.analysis.packing import coordination_number

    numba.set_num_threads(int(threads))

    sim = bed(state_file, cyl, size, young, rest, dt, skin, laws, orientations, sort)
    state = sim.state
    sim.run(steps=int(warm))
    t0 = time.perf_counter()
    sim.run(steps=int(steps))
    wall = time.perf_counter() - t0
    n = state.n
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    print(f"wall {wall:.6f}")
    print(f"zpp {coordination_number(sim):.4f}")
    print(f"particle_steps_per_s {n * int(steps) / wall:.4g} threads {threads} N {n} "
          f"array_bytes_per_grain {sim.memory_bytes() / n:.0f} peak_rss_bytes {rss} "
          f"rebuilds {sim.rebuilds} layer {numba.threading_layer()}")


if __name__ == "__main__":
    main(sys.argv[1:])
