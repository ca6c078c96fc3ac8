"""Split the error a procedure run makes in its extrapolated cycles into the estimator's
share and the bed's, from a folder's paths.csv alone (no DEM is run):

    python extrapolation_bias.py FOLDER[:RUN] ...

FOLDER holds paths.csv with full DEM's path ("full_dem") and a procedure run's (RUN;
default: the run whose name ends in _ki30_k10_h20).  For each jump of the run (from
cycle a, its last computed one, to cycle b) the procedure's own window, the k = 10
cycles before a, is replayed on full DEM's settlement path: the estimator is fitted to
full DEM's settlement at cycles a - 10..a and carried to b, as the procedure carries
its fit of the bed it computed:

* linear (Eq. 16): s_a + (b - a) (s_a - s_(a-10)) / 10;
* logarithmic: s_a + A ln(b / a), A the least-squares slope of s on ln N over the
  window (c + A ln N, N the cycle from the loading start).

The sum over the jumps of (replayed increment - full DEM's increment over a..b),
over full DEM's settlement at the end, is the estimator's share of the error: what the
jumps would add if every window read full DEM's own path.  The run's own share is the
sum of (the run's increment over a..b - full DEM's); their difference is the bed's
share: what the jumped, relaxed bed's windows read differently from full DEM's over
the same cycles.  Prints one row per folder, in % of full DEM's settlement at the end.
"""
import csv
import pathlib
import sys

import numpy as np

WINDOW = 10


def paths(folder):
    """{run: {cycle: (settlement [m], source)}} of ``folder``/paths.csv."""
    runs = {}
    with open(pathlib.Path(folder) / "paths.csv") as f:
        for r in csv.DictReader(f):
            runs.setdefault(r["run"], {})[int(r["cycle"])] = (float(r["settlement_m"]),
                                                              r["source"])
    return runs


def jumps(path):
    """(a, b) of each jump of a procedure ``path``: a the last computed cycle before
    it, b the first cycle after it."""
    cycles = sorted(path)
    return [(a, b) for a, b in zip(cycles, cycles[1:])
            if path[b][1] != "computed" or b != a + 1]


def replayed(full, a, b, law):
    """The increment over a..b that ``law`` fitted to full DEM's window a-10..a gives."""
    n = np.arange(a - WINDOW, a + 1)
    s = np.array([full[c] for c in n])
    if law == "linear":
        return (b - a) * (s[-1] - s[0]) / WINDOW
    x = np.log(n)
    slope = np.sum((x - x.mean()) * (s - s.mean())) / np.sum((x - x.mean()) ** 2)
    return slope * np.log(b / a)


def shares(folder, run=None):
    runs = paths(folder)
    full = {c: v[0] for c, v in runs["full_dem"].items()}
    run = run or next(r for r in runs if r.endswith("_ki30_k10_h20"))
    path = runs[run]
    end = max(path)
    scale = 100.0 / full[end]
    own = sum((path[b][0] - path[a][0]) - (full[b] - full[a]) for a, b in jumps(path))
    row = {"run": run, "jumps": len(jumps(path)), "own": scale * own,
           "error": scale * (path[end][0] - full[end])}
    for law in ("linear", "logarithmic"):
        row[law] = scale * sum(replayed(full, a, b, law) - (full[b] - full[a])
                               for a, b in jumps(path))
    row["bed"] = row["own"] - row[run.split("_")[0]]
    return row


if __name__ == "__main__":
    print("folder run jumps | error at the end | extrapolated share: run's own, "
          "replayed linear, replayed logarithmic, the bed's (own - replayed with the "
          "run's estimator) [%]")
    for arg in sys.argv[1:]:
        folder, _, run = arg.partition(":")
        r = shares(folder, run or None)
        print(f"{pathlib.Path(folder).name} {r['run']} {r['jumps']} | {r['error']:+.2f} | "
              f"{r['own']:+.2f} {r['linear']:+.2f} {r['logarithmic']:+.2f} {r['bed']:+.2f}")
