"""numba's threading layers side by side: the cost of entering a parallel region, and a
small deposition, on 1 and 2 threads under each layer that loads here.

    python benchmarks/threading_layers.py [--layers omp,workqueue,tbb] [--chunks 4]

Each (layer, threads) runs in its own process, numba's threads started on that layer
before graindyn is imported (lammps_bed.start_threads), so a layer graindyn refuses
(TBB) is timed too.  Prints, per case:
- ``region``: microseconds per call of a ``prange(2)`` region of 400 multiply-adds,
  called 500 times in a compiled loop, batch after batch (a growing cost shows a layer
  that leaks per region);
- ``deposition``: wall seconds per 0.005 s of simulated time of 400 spheres
  (examples/deposition_3d.toml, count = 400, in a cylinder of radius 4 mm), chunk
  after chunk, and the peak resident memory.
"""
import argparse
import json
import pathlib
import resource
import subprocess
import sys
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))


def region_costs(batches=6, calls=500):
    """Microseconds per parallel region, one value per batch of ``calls``."""
    import numba
    import numpy as np

    @numba.njit(parallel=True)
    def region(a):
        for b in numba.prange(2):
            s = 0.0
            for i in range(b * 200, (b + 1) * 200):
                s += a[i] * a[i]
            a[b] = s * 1e-9

    @numba.njit
    def many(a, count):
        for _ in range(count):
            region(a)

    a = np.random.default_rng(1).random(400)
    many(a, 1)
    costs = []
    for _ in range(batches):
        t = time.perf_counter()
        many(a, calls)
        costs.append((time.perf_counter() - t) / calls * 1e6)
    return costs


def deposition(chunks):
    """Wall seconds of each 0.005 s of simulated time of the 400-grain deposition."""
    import numpy as np

    from graindyn.config import build, load, validate

    config = load(ROOT / "examples" / "deposition_3d.toml")
    config.grains.count = 400
    data = config.model_dump()
    data["walls"]["container"] = {"kind": "cylinder", "radius": 4e-3, "height": 0.06}
    config = validate(data)
    protocol = build.protocol(config)
    sim = build.engine(config, build.sample(config, protocol,
                                            np.random.default_rng(config.run.seed)), protocol)
    sim.run(time=1e-4)                    # compile and first lists, untimed
    walls = []
    for _ in range(chunks):
        t = time.perf_counter()
        sim.run(time=0.005)
        walls.append(time.perf_counter() - t)
    return walls


def case(layer, threads, chunks):
    """One (layer, threads) measurement in this process."""
    from lammps_bed import start_threads

    start_threads(layer)
    import numba
    numba.set_num_threads(threads)
    result = {"layer": numba.threading_layer(), "threads": threads,
              "region_us": region_costs(), "deposition_s": deposition(chunks)}
    result["peak_rss_MB"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e3
    print(json.dumps(result))


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--layers", default="omp,workqueue,tbb")
    ap.add_argument("--threads", default="1,2")
    ap.add_argument("--chunks", type=int, default=4)
    ap.add_argument("--timeout", type=float, default=600, help="seconds per case")
    ap.add_argument("--case", nargs=2, metavar=("LAYER", "THREADS"), help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.case:
        return case(a.case[0], int(a.case[1]), a.chunks)
    print("| layer | threads | region us (batch after batch) | deposition s per 0.005 s "
          "(chunk after chunk) | peak RSS MB |")
    print("|---|---:|---|---|---:|")
    for layer in a.layers.split(","):
        for threads in (int(t) for t in a.threads.split(",")):
            try:
                out = subprocess.run([sys.executable, __file__, "--case", layer, str(threads),
                                      "--chunks", str(a.chunks)], capture_output=True,
                                     text=True, timeout=a.timeout)
            except subprocess.TimeoutExpired:
                print(f"| {layer} | {threads} | over {a.timeout:.0f} s | | |", flush=True)
                continue
            lines = [l for l in out.stdout.splitlines() if l.startswith("{")]
            if out.returncode or not lines:
                print(f"| {layer} | {threads} | failed: {out.stderr.strip()[-200:]} | | |")
                continue
            r = json.loads(lines[-1])
            print(f"| {r['layer']} | {threads} | "
                  + ", ".join(f"{c:.1f}" for c in r["region_us"]) + " | "
                  + ", ".join(f"{w:.3f}" for w in r["deposition_s"])
                  + f" | {r['peak_rss_MB']:.0f} |", flush=True)


if __name__ == "__main__":
    main()
