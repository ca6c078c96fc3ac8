"""Cold and warm start: the wall time of a fresh process that imports graindyn and runs
300 steps of two Hertz-Mindlin spheres, with an empty compile cache (cold: everything
compiles) and again with the cache it left (warm: everything loads).

    python benchmarks/start_up.py [--repeats 3]

Run a tree other than the installed one with PYTHONPATH=TREE/src.  Prints one line per
start and the medians.
"""
import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time

RUN = """
import numpy as np
import graindyn as gd
state = gd.State.create(np.array([[0.0, 0.0, 1.2e-3], [0.0, 0.0, 3.5e-3]]), [1e-3, 1e-3],
                        2650.0)
model = gd.ContactModel("hertz", "tsuji", "mindlin")
sim = gd.Simulation(state, [gd.Material(restitution=0.9)], model,
                    walls=gd.box((-5e-3, -5e-3, 0.0), (5e-3, 5e-3, 1e-2)))
sim.run(steps=300)
"""


def start(cache):
    """Seconds of one fresh process with GRAINDYN_CACHE_DIR = cache."""
    env = {**os.environ, "GRAINDYN_CACHE_DIR": cache}
    t = time.perf_counter()
    subprocess.run([sys.executable, "-c", RUN], env=env, check=True)
    return time.perf_counter() - t


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    cold, warm = [], []
    for k in range(args.repeats):
        with tempfile.TemporaryDirectory() as cache:
            cold.append(start(cache))
            warm.append(start(cache))
        print(f"start {k}: cold {cold[-1]:.2f} s, warm {warm[-1]:.2f} s", flush=True)
    print(f"median: cold {statistics.median(cold):.2f} s, warm {statistics.median(warm):.2f} s")


if __name__ == "__main__":
    main()
