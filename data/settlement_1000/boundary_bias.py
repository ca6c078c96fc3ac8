"""How the smoothing of the procedure treats the grains under the plate, in full DEM
(no procedure involved): for every ten-cycle window of a full DEM run (cycles c to
c + 10, c = 30, 40, ...), each grain's least-squares rate over the window, smoothed
over w mean radii by the Gaussian mean and by the local linear fit
(analysis.settlement.smooth_increments), and the vertical rate of the grains within
three mean radii of the highest one summed over the windows, over the same sum
unsmoothed:

    python boundary_bias.py STUDY [STUDY ...]

STUDY: a `graindyn study settlement` folder whose full DEM run kept its residuals
(runs/full_dem/residuals) and its bed (bed/settled.h5, the positions at cycle 0).
"""
import pathlib
import sys

import h5py
import numpy as np

from graindyn.analysis.settlement import smooth_increments
from graindyn.protocols.cyclic import load_residuals

WIDTHS = (1.5, 3.0)             # [mean radii]
WINDOW = 10                     # computed cycles of a window


def top_layer_ratios(study):
    """{(fit, width): smoothed / unsmoothed vertical rate of the top layer, summed over
    the windows}, and the number of windows."""
    study = pathlib.Path(study)
    u = load_residuals(study / "runs" / "full_dem")
    u = np.concatenate([np.zeros((1,) + u.shape[1:]), u])       # u(0) = 0
    with h5py.File(study / "bed" / "settled.h5") as f:
        x0 = f["grains/positions"][:]
        radius = float(np.mean(f["grains/radii"][:]))
    sums = {(fit, w): 0.0 for fit in ("mean", "linear") for w in WIDTHS}
    raw, windows = 0.0, 0
    cycles = np.arange(WINDOW + 1.0)
    for c in range(30, u.shape[0] - WINDOW, WINDOW):
        window = u[c:c + WINDOW + 1].reshape(WINDOW + 1, -1)
        rate = np.polyfit(cycles, window, 1)[0].reshape(u.shape[1], 3)
        x = x0 + u[c + WINDOW]
        top = x[:, 2] > x[:, 2].max() - 3.0 * radius
        raw += rate[top, 2].sum()
        for fit, w in sums:
            sums[fit, w] += smooth_increments(x, rate, w * radius, fit=fit)[top, 2].sum()
        windows += 1
    return {key: value / raw for key, value in sums.items()}, windows


if __name__ == "__main__":
    for study in sys.argv[1:]:
        ratios, windows = top_layer_ratios(study)
        print(f"{study}: {windows} windows; top layer's smoothed / unsmoothed descent: "
              + ", ".join(f"{fit} {w:g} radii {r:.3f}" for (fit, w), r in ratios.items()))
