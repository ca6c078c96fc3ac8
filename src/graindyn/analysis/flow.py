"""The discharge rate of a silo against the size of its hole: the Beverloo law.

A flat-bottomed silo discharges at a rate independent of the height of the column
(Janssen's saturation of the pressure at the bottom), set by the hole alone.  In 2D (a
slot of width d_h in a layer of disks of mean diameter d), Beverloo's dimensional
argument gives the rate in disks per second

    Q = C sqrt(g) (d_h - k d)^(3/2) / d^2 = A (R - k)^(3/2),    R = d_h / d,

with A = C sqrt(g / d) [1/s]: the grains near the hole fall freely over a length of the
order of the hole (velocity ~ sqrt(g d_h)) through an opening narrowed by an empty
annulus of about k d/2 on each side (k ~ 1-3 in experiments).  C [-] holds the packing
fraction at the outlet.  ``fit_beverloo`` fits A and k to measured rates; C follows.
"""
import math

import numpy as np
from scipy.optimize import curve_fit


def beverloo(R, A, k):
    """Q [1/s] = A (R - k)^(3/2), zero for R <= k (Beverloo in 2D, in hole sizes R)."""
    return A * np.clip(np.asarray(R, dtype=float) - k, 0.0, None) ** 1.5


def fit_beverloo(R, rate, rate_err=None, d=None, g=None):
    """Fit Q(R) = A (R - k)^(3/2) to the rates ``rate`` [1/s] at hole sizes R [-],
    weighted by ``rate_err`` when every error is given and positive (else unweighted,
    the errors then from the residuals).  Start: k from the straight line of Q^(2/3)
    against R, which Beverloo makes exact.  Returns A, k and their errors, chi2 per
    degree of freedom (weighted fits only), dof, and C = A sqrt(d/g) [-] when the mean
    diameter ``d`` [m] and gravity ``g`` [m/s^2] are given; {"error": ...} when it cannot
    fit."""
    R, rate = np.asarray(R, dtype=float), np.asarray(rate, dtype=float)
    keep = np.isfinite(R) & np.isfinite(rate) & (rate > 0)
    sigma = None
    if rate_err is not None:
        err = np.asarray(rate_err, dtype=float)
        if np.all(np.isfinite(err[keep]) & (err[keep] > 0)):
            sigma = err[keep]
    R, rate = R[keep], rate[keep]
    dof = R.size - 2
    if dof < 1:
        return {"error": f"{R.size} flowing hole sizes cannot fit A and k"}
    slope, intercept = np.polyfit(R, rate ** (2.0 / 3.0), 1)
    if slope <= 0:
        return {"error": "the rate does not grow with the hole"}
    start = (slope ** 1.5, min(-intercept / slope, R.min() - 0.1))
    try:
        p, cov = curve_fit(beverloo, R, rate, p0=start, sigma=sigma,
                           absolute_sigma=sigma is not None, maxfev=20000)
    except (RuntimeError, ValueError) as failure:
        return {"error": str(failure)}
    out = {"A": float(p[0]), "k": float(p[1]), "dof": dof}
    for name, var in zip(("A", "k"), np.diag(cov)):
        out[f"{name}_err"] = float(math.sqrt(var)) if np.isfinite(var) else float("nan")
    if sigma is not None:
        out["chi2_per_dof"] = float(np.sum(((beverloo(R, *p) - rate) / sigma) ** 2) / dof)
    if d is not None and g is not None:
        scale = math.sqrt(d / g)
        out["C"] = out["A"] * scale
        out["C_err"] = out["A_err"] * scale
    return out
