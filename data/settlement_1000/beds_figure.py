"""The procedure's settlement against full DEM of the same bed along the cycles, one
line per bed and the mean over the beds, for one or more settings side by side.

    python beds_figure.py OUT.png LABEL=FOLDER[,FOLDER...] [LABEL=FOLDER,... ...]

Each FOLDER holds a paths.csv (README) with one full DEM run and one procedure run.
Draws, per setting, (s_procedure / s_full - 1) at every cycle the procedure computed
or jumped to, and prints the mean and standard deviation over the beds at cycle 1000
(the last)."""
import csv
import pathlib
import sys

import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt     # noqa: E402
import numpy as np                  # noqa: E402


def relative_path(folder):
    """(cycles, s_procedure / s_full - 1) of the procedure run in ``folder`` against
    its full DEM run (a replica's, full_dem_replica_N, where that is the one held)."""
    runs = {}
    for row in csv.DictReader(open(folder / "paths.csv")):
        runs.setdefault(row["run"], {})[int(row["cycle"])] = float(row["settlement_m"])
    references = [name for name in runs if name.startswith("full_dem")]
    procedures = [name for name in runs if not name.startswith("full_dem")]
    if len(references) != 1 or len(procedures) != 1:
        raise SystemExit(f"{folder}: one full DEM run and one procedure run expected, "
                         f"found {sorted(runs)}")
    full, own = runs[references[0]], runs[procedures[0]]
    cycles = np.array(sorted(c for c in own if c in full))
    return cycles, np.array([own[c] / full[c] - 1.0 for c in cycles])


def main(out, settings):
    fig, axes = plt.subplots(1, len(settings), figsize=(5.5 * len(settings), 4.2),
                             sharey=True, squeeze=False)
    grid = np.arange(30, 1001)
    for ax, (label, folders) in zip(axes[0], settings):
        curves = []
        for folder in folders:
            cycles, error = relative_path(folder)
            ax.plot(cycles, 100 * error, lw=0.8, alpha=0.7, label=folder.name)
            curves.append(np.interp(grid, cycles, error))
        curves = np.array(curves)
        ax.plot(grid, 100 * curves.mean(axis=0), "k", lw=2, label="mean")
        ax.axhline(0.0, color="0.5", lw=0.6)
        ax.axhspan(-1.0, 1.0, color="0.85", zorder=0)
        ax.set_title(f"{label}: {len(folders)} beds")
        ax.set_xlabel("cycle")
        ax.legend(fontsize=7)
        last = curves[:, -1]
        print(f"{label}: at cycle 1000 {100 * last.mean():+.2f} % mean, "
              f"{100 * last.std(ddof=1):.2f} % standard deviation, "
              f"{100 * last.std(ddof=1) / np.sqrt(last.size):.2f} % standard error; "
              + ", ".join(f"{100 * e:+.2f}" for e in last))
    axes[0][0].set_ylabel("procedure / full DEM - 1 [%]")
    fig.tight_layout()
    fig.savefig(out, dpi=120)


if __name__ == "__main__":
    main(pathlib.Path(sys.argv[1]),
         [(a.partition("=")[0], [pathlib.Path(f) for f in a.partition("=")[2].split(",")])
          for a in sys.argv[2:]])
