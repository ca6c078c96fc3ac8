"""GPU speed of graindyn: one large bed, or an ensemble of small ones.

    python benchmarks/gpu_bench.py bed STATE SIZE NX NY WARM STEPS
    python benchmarks/gpu_bench.py ensemble STATE RADIUS K WARM STEPS

bed: the settled bed STATE (x y z r per line, as written by ../shared/bench; the
state_settle_10000.txt bed has SIZE = 0.024) tiled NX x NY in one open box, with the
physics of the issue's anchor (monodisperse 1 mm spheres, Hertz-Mindlin with Tsuji
damping from e = 0.9, E = 1e8 Pa, nu = 0.3, mu = 0.5, rho = 2650, dt = 2e-6 s), run on
backend gpu: WARM untimed steps, then STEPS timed.  NX = NY = 10 gives 1e6 grains,
32 x 32 about 1e7.
ensemble: K copies of the 280-grain oedometer bed STATE (state_oedo_280.txt, in a
cylinder of RADIUS = 0.004 m on a floor; E = 1e9 Pa, dt = 1e-7 s as in ../shared/bench)
with sliding friction spread over 0.3-0.7, advanced as one graindyn.Ensemble.

Prints particle-steps per second (summed over the members), device bytes per grain,
and the bytes of the arrays handed to the per-grain kernels per particle-step (each
array counted once per launch: an estimate of the memory traffic) with the fraction of
BANDWIDTH bytes/s (environment variable, default 3.0e12, the H100 of the issue) it
implies, and how often the host read the run table back (engine.DeviceEnsemble._batch)
against the rebuilds.  Under NUMBA_ENABLE_CUDASIM=1 it runs (slowly) for a smoke test only.
"""
import os
import sys
import time

import numpy as np


def bed(argv):
    from memory_tiled import tiled

    state, size, nx, ny = argv[0], float(argv[1]), int(argv[2]), int(argv[3])
    return [tiled(state, size, nx, ny, "gpu")]


def ensemble(argv):
    import graindyn as gd

    data = np.loadtxt(argv[0], ndmin=2)
    radius, k = float(argv[1]), int(argv[2])
    sims = []
    for mu in np.linspace(0.3, 0.7, k):
        state = gd.State.create(data[:, :3], data[:, 3], 2650.0)
        grain = gd.Material("bed", density=2650.0, youngs_modulus=1e9, poisson_ratio=0.3,
                            restitution=0.9, friction_sliding=float(mu),
                            tangential_damping=1.0)
        walls = [gd.Cylinder((0, 0, 0), (0, 0, 1), radius), gd.Plane((0, 0, 0), (0, 0, 1))]
        sims.append(gd.Simulation(state, [grain], gd.ContactModel(
            "hertz", "tsuji", "mindlin", limit_damping=False), walls=walls, dt=1e-7,
            skin=1e-4, check_interval=1000, backend="gpu"))
    return sims


def main(argv):
    if not argv or (argv[0], len(argv)) not in (("bed", 7), ("ensemble", 6)):
        sys.exit(__doc__)
    import graindyn as gd

    sims = (bed if argv[0] == "bed" else ensemble)(argv[1:-2])
    warm, steps = int(argv[-2]), int(argv[-1])
    group = gd.Ensemble(sims)
    group.run(steps=warm)
    engine = group._device
    engine.count_bytes = True
    n = sum(s.state.n for s in sims)
    reads, rebuilds = engine.reads, sum(s.rebuilds for s in sims)
    t0 = time.perf_counter()
    group.run(steps=steps)
    wall = time.perf_counter() - t0
    reads, rebuilds = engine.reads - reads, sum(s.rebuilds for s in sims) - rebuilds
    per_step = engine.launched_bytes / (steps * n)
    rate = n * steps / wall
    bandwidth = float(os.environ.get("BANDWIDTH", 3.0e12))
    print(f"case {argv[0]} members {len(sims)} N {n} steps {steps} wall {wall:.4f}")
    print(f"particle_steps_per_s {rate:.4g}")
    print(f"device_bytes_per_grain {engine.memory_bytes() / n:.0f}")
    print(f"kernel_bytes_per_particle_step {per_step:.0f} bandwidth_fraction "
          f"{rate * per_step / bandwidth:.3f}")
    print(f"host_reads {reads} rebuilds {rebuilds} (summed over members) in {steps} steps")


if __name__ == "__main__":
    main(sys.argv[1:])
