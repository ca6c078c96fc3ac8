"""Cost of the load cycles of a cyclic run (protocols/cyclic.py) on 1, 2, ... threads.

    python benchmarks/cyclic_cycles.py RUN_DIR [--cycles K] [--threads 1 2]

RUN_DIR is a finished (or interrupted) run of a cyclic config, e.g. of
examples/cyclic.toml: its latest checkpoint, the settled (and perhaps already loaded)
bed, is restored into a fresh engine built from the run's config, and K load cycles
of that config (the plate put back on the bed, the same haversine) are run and timed
on each thread count in turn, each from the same restored state.  Prints, per thread
count, the wall time per cycle, cycles per hour, particle-steps per second and the
peak resident memory, and the settlement the K cycles made (the same on every thread
count up to rounding: the blocks of grains differ).
"""
import argparse
import resource
import time

import numpy as np


def cycles_once(run_dir, cycles, threads):
    import numba

    from graindyn.config import build, load
    from graindyn.core.state import State
    from graindyn.output import checkpoint

    numba.set_num_threads(threads)
    config = load(f"{run_dir}/config.toml")
    config.protocol.cycles = cycles
    config.protocol.residuals = False
    arrays, _, _, _ = checkpoint.latest(f"{run_dir}/checkpoints")
    materials = arrays["grains/materials"]
    density = np.array([m.density for m in config.materials])[materials]
    state = State.create(arrays["grains/positions"], arrays["grains/radii"], density,
                         dim=config.run.dim, materials=materials)
    protocol = build.protocol(config)
    engine = build.engine(config, state, protocol)
    engine.restore(arrays)
    phase = protocol.phases[-1]
    phase_state = {}
    start, step0 = time.perf_counter(), engine.step
    phase.run(engine, phase_state)
    wall = time.perf_counter() - start
    steps = engine.step - step0
    settlement = phase_state["rows"][-1]["settlement_m"]
    return wall, steps, engine.state.n, settlement


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dir")
    parser.add_argument("--cycles", type=int, default=2)
    parser.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    args = parser.parse_args()
    cycles_once(args.run_dir, 1, args.threads[0])        # compile and warm the caches
    print("threads  wall s/cycle  cycles/hour  particle-steps/s  settlement mm  peak RSS MB")
    for threads in args.threads:
        wall, steps, n, settlement = cycles_once(args.run_dir, args.cycles, threads)
        rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
        print(f"{threads:7d}  {wall / args.cycles:12.2f}  {3600 * args.cycles / wall:11.1f}  "
              f"{n * steps / wall:16.3g}  {1e3 * settlement:13.4f}  {rss:11.0f}")


if __name__ == "__main__":
    main()
