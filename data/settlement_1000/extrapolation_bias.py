"""Split the error a procedure run makes in its extrapolated cycles into the estimator's
share and the bed's, from a folder's paths.csv alone (no DEM is run):

    python extrapolation_bias.py FOLDER[:RUN] ...

FOLDER holds paths.csv with full DEM's path ("full_dem") and a procedure run's (RUN;
default: the run whose name ends in _ki30_k10_h20, its estimator the name's first
word).  studies.settlement_beds.error_shares replays each jump's window (the k = 10
cycles before it, at 50 Hz) on full DEM's path with the run's estimator, and with the
other of the linear and logarithmic laws for comparison.  Prints one row per folder:
the error at the end, then the extrapolated cycles' share of it, the replayed
estimator's share (the run's, then the other law's) and the bed's, each in % of full
DEM's settlement at the end.
"""
import csv
import pathlib
import sys

from graindyn.studies.settlement_beds import error_shares

WINDOW = 10            # computed cycles k of the runs [-]
PERIOD = 1.0 / 50.0    # the fully confined load's period [s]


def paths(folder):
    """{run: [(cycle, settlement [m], source)]} of ``folder``/paths.csv."""
    runs = {}
    with open(pathlib.Path(folder) / "paths.csv") as f:
        for r in csv.DictReader(f):
            runs.setdefault(r["run"], []).append((int(r["cycle"]), float(r["settlement_m"]),
                                                  r["source"]))
    return runs


def main(arguments):
    print("folder run | error at the end | extrapolated share, estimator's (the run's "
          "law, the other law), bed's [%]")
    for arg in arguments:
        folder, _, run = arg.partition(":")
        runs = paths(folder)
        run = run or next(r for r in runs if r.endswith("_ki30_k10_h20"))
        law = run.split("_")[0]
        other = "logarithmic" if law == "linear" else "linear"
        full, path = runs["full_dem"], runs[run]
        end = max(path)[0]
        scale = 100.0 / dict((c, s) for c, s, _ in full)[end]
        own = error_shares(path, full, law, WINDOW, PERIOD)
        replay = error_shares(path, full, other, WINDOW, PERIOD)["estimator"]
        error = max(path)[1] - dict((c, s) for c, s, _ in full)[end]
        print(f"{pathlib.Path(folder).name} {run} | {scale * error:+.2f} | "
              f"{scale * own['extrapolated']:+.2f}, {scale * own['estimator']:+.2f} "
              f"({other} {scale * replay:+.2f}), {scale * own['bed']:+.2f}")


if __name__ == "__main__":
    main(sys.argv[1:])
