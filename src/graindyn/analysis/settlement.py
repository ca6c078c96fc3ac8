"""Estimation and extrapolation of residual displacements under cyclic loading
(Karrech et al. 2007, Sec. 3, Eq. 8-22).

Data.  ``displacements`` (k + 1, N, 3) [m]: the residual displacement of each grain at
the end of each cycle of a training window, record 0 being the window's start t_0 = t
and record p the end of cycle p, t_p = t + pT (p = 1..k); ``times`` (k + 1,) [s] (or
cycle numbers: any increasing abscissa, > 0 for the logarithmic law).  Displacements
are measured from any fixed reference configuration (usually the configuration at t_0,
so that record 0 is zero: the records of a cyclic run are
``np.concatenate([np.zeros((1, N, 3)), protocols.cyclic.load_residuals(run_dir)])``).

Linear estimator (Eq. 16).  The residual increment per cycle is estimated by the mean
of the k recorded increments, the least-squares estimate of a constant increment;
the sum telescopes, so the rate is (u_k - u_0)/(t_k - t_0) and

    u^(t_k+h) = u(t_k) + (t_k+h - t_k) (u_k - u_0)/(t_k - t_0)       (Eq. 16).

Logarithmic estimator (Shenton's law, Eq. 17-21).  u~(t) = a ln t + b t, fitted per
grain and component to the k training records p = 1..k by least squares (Eq. 18); the
closed forms Eq. 20-21 are the normal equations of this two-column fit, so the paper
fits no intercept.  Without an intercept the law depends on the unit and origin of t
and on the reference of the displacements (it forces u~ through the law's own zero);
``intercept=True`` adds a constant column, u~ = c + a ln t + b t, which removes that
dependence (use it when the window starts after k_i initial cycles and the
displacements are measured from its start).  The extrapolation adds to the last known
displacement the increment of the fitted law:

    u^(t_k+h) = u(t_k) + [u~(t_k+h) - u~(t_k)].

This is our reading of Eq. 17, whose printed form u(t_k) + u~(t_k+h) would count the
displacement already accrued twice: on data that follow the law exactly it would give
about 2 u; the text says the second term is the estimated residual displacement
after the last step, as the h/k term of Eq. 16 is.

Logarithmic law (``"logarithmic"``).  u~(t) = c + a ln t, fitted per grain and
component by least squares with its constant to every record at t > 0 (all k + 1 on
the loading's clock, t_p = pT from the first cycle): the settlement law of ballast under repeated load, s_N = s_1 + a ln N
(Shenton's own form, the one Karrech et al. cite; Eq. 17 adds the term b t to it).
Its increment from t_k to t_k + h, a ln(1 + h / t_k), falls as 1 / t the way a
settling bed's rate does, where Eq. 16 carries the window's rate on unchanged: on
data that follow the law the linear estimator overshoots by a [h / t_k - ln(1 + h /
t_k)] plus what the window's own curvature adds.  On a window far from t = 0 the
design [1, ln t] is well conditioned where [1, ln t, t] is not (below).

Least squares.  The design matrix [ln t_p, t_p] (or [1, ln t_p, t_p]) is the same for
every grain and component, so it is factored once by a thin QR of the matrix with its
columns scaled to unit norm, and the k x 3N right-hand side is solved in one
triangular solve.  The normal equations (Eq. 20-21) square the condition number of the
design, which grows large as the window moves away from t = 0 (ln t and t become nearly
collinear): for 40 cycles at 50 Hz it is about 4e2 without and 8e4 with the intercept
at t = 10 s, 1e4 and 2e8 at t = 100 s (1e3 and 4e6 once the columns are scaled), so
the normal equations would lose up to 16 digits; they are not used.

Error measures (Eq. 13-14, 22), with the paper's second norm over all grains, cycles
and components: g_u(k) = (1/k) ||u_p - u_p-1||, f_xi(k) = (1/k) ||xi||, with xi_p the
residual of the fitted trend at the training records, and E_r(u) = ||u - u^|| / ||u||
over the N x 3 matrix.

The Chernoff bound (Eq. 15).  For k independent errors xi_p in [a, b], Hoeffding's
inequality (the Chernoff bound of the paper) gives

    Pr[ |(1/k) sum_p xi_p - E xi| >= eps ] <= 2 exp(-2 k eps^2 / (b - a)^2),

which we read as the paper's garbled exponent (its pi is eps) with zero-mean errors;
the bound is at most P when k >= (b - a)^2 / (2 eps^2) ln(2 / P) (the paper's
"(b - a)^2 / (2 v^2) ln(a / 2)" with v = eps and the fraction inverted, since the
logarithm must be positive).
"""
from typing import NamedTuple

import math

import numpy as np
from scipy.linalg import solve_triangular
from scipy.spatial import cKDTree

LAWS = ("linear", "shenton", "logarithmic")


class ResidualTrend(NamedTuple):
    """A trend fitted to the residual displacements of a training window.

    law : "linear" (Eq. 16), "shenton" (Eq. 17-21) or "logarithmic" (c + a ln t)
    intercept : whether the fit has a constant term (False: the paper's Shenton fit;
      always True for the logarithmic law)
    coefficients : (m, N, 3) per grain and component, in the order of ``basis``:
      linear: (rate [m/s],) per unit of ``times``; shenton: (a [m], b [m/s]) or
      (c [m], a [m], b [m/s]) with the intercept; logarithmic: (c [m], a [m])
    times : (k + 1,) the training abscissae t_0..t_k
    last : (N, 3) [m] the last recorded displacement u(t_k)
    residuals : (k, N, 3) [m] xi_p = u_p - u~(t_p) at p = 1..k (Eq. 14, 18); for the
      linear trend u~(t_p) = u_0 + rate (t_p - t_0)
    """

    law: str
    intercept: bool
    coefficients: np.ndarray
    times: np.ndarray
    last: np.ndarray
    residuals: np.ndarray

    def trend(self, times):
        """The fitted law u~ at ``times`` (T,): (T, N, 3) [m] (the linear trend relative
        to u_0, the Shenton law as fitted)."""
        t = np.asarray(times, dtype=np.float64).reshape(-1)
        if self.law == "linear":
            return (t - self.times[0])[:, None, None] * self.coefficients[0]
        return np.einsum("tm,mnd->tnd", _basis(self.law, t, self.intercept),
                         self.coefficients)

    def extrapolate(self, time):
        """u^ at ``time`` (a scalar after t_k): the last known displacement plus the
        increment of the trend from t_k (Eq. 16 and our reading of Eq. 17); (N, 3) [m]."""
        time = float(time)
        t_k = self.times[-1]
        if not time >= t_k:
            raise ValueError(f"extrapolation time {time} is before the last record {t_k}")
        step = self.trend([time])[0] - self.trend([t_k])[0]
        return self.last + step

    def extrapolate_cycles(self, h):
        """u^ after h further cycles, t_k + h T with T the (uniform) spacing of
        ``times``; (N, 3) [m]."""
        spacing = np.diff(self.times)
        if not np.allclose(spacing, spacing[0], rtol=1e-9, atol=0.0):
            raise ValueError("times are not evenly spaced: give the time to extrapolate()")
        if h < 0:
            raise ValueError(f"h must be >= 0 cycles, got {h}")
        return self.extrapolate(self.times[-1] + h * spacing[0])


def _check(displacements, times):
    u = np.asarray(displacements, dtype=np.float64)
    t = np.asarray(times, dtype=np.float64).reshape(-1)
    if u.ndim != 3 or u.shape[2] != 3 or u.shape[0] != t.size:
        raise ValueError(f"displacements must be (k + 1, N, 3) with one time per record, got "
                         f"{u.shape} and {t.size} times")
    if t.size < 2 or np.any(np.diff(t) <= 0) or not np.all(np.isfinite(u)):
        raise ValueError("need at least two records at increasing times, finite displacements")
    return u, t


def _basis(law, t, intercept):
    """The design columns of the Shenton (ln t, t) or logarithmic (ln t) law at ``t``,
    the constant first when ``intercept``."""
    columns = [np.log(t), t] if law == "shenton" else [np.log(t)]
    if intercept:
        columns.insert(0, np.ones_like(t))
    return np.stack(columns, axis=1)


def lstsq_shared(design, values):
    """Least-squares coefficients of ``values`` (k, ...) on the ``design`` (k, m) shared
    by every column of values: (m, ...).  The design's columns are scaled to unit norm,
    factored once by a thin QR and the triangular system solved for all right-hand
    sides at once (never the normal equations, which square the condition number)."""
    k = design.shape[0]
    if k < design.shape[1]:
        raise ValueError(f"{design.shape[1]} coefficients need at least as many records, "
                         f"got {k}")
    scale = np.linalg.norm(design, axis=0)
    q, r = np.linalg.qr(design / scale)
    flat = values.reshape(k, -1)
    coefficients = solve_triangular(r, q.T @ flat) / scale[:, None]
    return coefficients.reshape((design.shape[1],) + values.shape[1:])


def fit_residual(displacements, times, law="shenton", intercept=False):
    """Fit the ``law`` ("linear", Eq. 16; "shenton", Eq. 17-21; "logarithmic", c + a ln
    t, which always has its constant) to the residual displacements (k + 1, N, 3) [m]
    recorded at ``times`` (k + 1,) (module docstring); returns a ResidualTrend."""
    u, t = _check(displacements, times)
    if law == "linear":
        if intercept:
            raise ValueError("the linear estimator (Eq. 16) has no intercept option")
        rate = (u[-1] - u[0]) / (t[-1] - t[0])
        fitted = u[0] + (t[1:] - t[0])[:, None, None] * rate
        return ResidualTrend(law, False, rate[None], t, u[-1].copy(), u[1:] - fitted)
    if law not in LAWS:
        raise ValueError(f"law must be one of {LAWS}, got {law!r}")
    if t[1] <= 0:
        raise ValueError(f"the {law} law needs times > 0 (it takes ln t)")
    intercept = intercept or law == "logarithmic"
    # Shenton's law is fitted to the records p = 1..k (Eq. 18); the logarithmic law,
    # whose constant frees it from the reference, to every record where ln t exists
    used = slice(1, None) if law == "shenton" or t[0] <= 0 else slice(None)
    coefficients = lstsq_shared(_basis(law, t[used], intercept), u[used])
    fitted = np.einsum("tm,mnd->tnd", _basis(law, t[1:], intercept), coefficients)
    return ResidualTrend(law, bool(intercept), coefficients, t, u[-1].copy(), u[1:] - fitted)


FITS = ("mean", "linear")


def smooth_increments(positions, increments, length, planes=(), fit="mean"):
    """The extrapolated increments (N, 3) [m] of grains at ``positions`` (N, 3) [m]
    averaged over their neighbourhood, the grains within 3 ``length`` [m] weighted by
    the Gaussian exp(-r^2 / (2 length^2)) of their distance r (its own with weight 1):
    ``fit`` = "mean", each grain's increment replaced by the weighted mean (a
    Nadaraya-Watson average), or "linear", by the value at the grain of the affine
    field u(y) = a + G (y - x) fitted to the neighbourhood by weighted least squares
    (local linear regression).

    Why: each grain's trend is fitted to its own path, which carries the bed's noise
    (a grain that rattled or slipped once during the window), and extrapolating that
    noise over h cycles drives neighbours into each other by up to a radius, which the
    relaxation must then undo.  A smooth field of increments moves touching grains
    alike, so it changes their overlaps only by the field's gradient times their
    distance.  Why "linear": the mean keeps an affine field only where the
    neighbourhood is symmetric about the grain; next to a wall, the floor or the plate
    it is one-sided, and the mean pulls each grain's increment towards those of the
    grains inside.  Under a plate that compresses the bed the top grains' descent is
    then cut by about the strain rate times 0.8 length: in full DEM windows of the
    settlement study's beds the top three radii's smoothed descent is 0.76-0.87 of the
    unsmoothed one at length = 3 mean radii and 0.95-0.96 at 1.5
    (docs/settlement.md).  The local linear fit reproduces an affine field at every
    grain, inside or at a boundary (the known boundary correction of kernel
    smoothing).  ``planes``: the symmetry planes [(axis, at)] of a model cut by them
    (core/symmetry.py): the grains within 3 length of a plane enter again as their
    mirror images, the component normal to the plane reversed, so that a grain beside
    the plane averages over both sides as in the whole bed (and its normal increment
    tends to zero at the plane, as the symmetry requires).  length = 0 returns the
    increments unchanged."""
    if fit not in FITS:
        raise ValueError(f"fit must be one of {FITS}, got {fit!r}")
    x = np.asarray(positions, dtype=np.float64)
    u = np.asarray(increments, dtype=np.float64)
    if not length > 0:
        return u.copy()
    reach = 3.0 * length
    sources, values = [x], [u]
    for axis, at in planes:                     # each plane, then each pair of them
        for k in range(len(sources)):
            near = np.abs(sources[k][:, axis] - at) < reach
            image, value = sources[k][near].copy(), values[k][near].copy()
            image[:, axis] = 2.0 * at - image[:, axis]
            value[:, axis] *= -1.0
            sources.append(image)
            values.append(value)
    cloud, carried = np.concatenate(sources), np.concatenate(values)
    pairs = cKDTree(x).sparse_distance_matrix(cKDTree(cloud), reach, output_type="ndarray")
    i, j = pairs["i"], pairs["j"]
    weight = np.exp(-0.5 * (pairs["v"] / length) ** 2)
    n = x.shape[0]
    if fit == "mean":
        total = np.bincount(i, weight, minlength=n)
        out = np.empty_like(u)
        for d in range(u.shape[1]):
            out[:, d] = np.bincount(i, weight * carried[j, d], minlength=n) / total
        return out
    # the normal equations of each grain's weighted fit, in offsets scaled by length
    design = np.concatenate([np.ones((i.size, 1)), (cloud[j] - x[i]) / length], axis=1)
    m = design.shape[1]
    normal = np.empty((n, m, m))
    right = np.empty((n, m, u.shape[1]))
    for a in range(m):
        wa = weight * design[:, a]
        for b in range(a, m):
            normal[:, a, b] = normal[:, b, a] = np.bincount(i, wa * design[:, b],
                                                            minlength=n)
        for d in range(u.shape[1]):
            right[:, a, d] = np.bincount(i, wa * carried[j, d], minlength=n)
    # a gradient the neighbourhood cannot fix (a grain alone, grains in a plane or on
    # a line) is held to zero by a ridge far below any resolved one
    normal[:, 1:, 1:] += 1e-12 * normal[:, :1, :1] * np.eye(m - 1)
    return np.linalg.solve(normal, right)[:, 0, :]


def forecast_errors(settlement, window, horizon, first=0):
    """Relative errors [-] of the linear estimator (Eq. 16) applied to a settlement path
    itself: from each record c >= first + window whose c + horizon is recorded, the
    forecast s_c + horizon (s_c - s_(c-window)) / window against s_(c+horizon), over
    s_(c+horizon).  ``settlement`` (n,) [m]: one record per cycle, record p at the end
    of cycle p.

    Applied to full DEM, it tells how far ahead the bed's own settlement can be told
    from a window of its past: the bursts of settlement a window does not contain (a
    few grains' arches giving way) make the spread of these errors a floor under the
    error of any jump of ``horizon`` cycles that rests on ``window`` computed ones."""
    s = np.asarray(settlement, dtype=float)
    if window < 1 or horizon < 1:
        raise ValueError(f"window and horizon must be >= 1 cycle, got {window}, {horizon}")
    c = np.arange(first + window, s.size - horizon)
    if c.size == 0:
        raise ValueError(f"{s.size} records hold no window of {window} cycles from record "
                         f"{first} with {horizon} more after it")
    forecast = s[c] + horizon * (s[c] - s[c - window]) / window
    return (forecast - s[c + horizon]) / s[c + horizon]


def increment_norm(displacements):
    """g_u(k) (Eq. 13) [m]: (1/k) times the second norm of the k per-cycle increments
    u_p - u_p-1 over all grains and components."""
    u = np.asarray(displacements, dtype=np.float64)
    k = u.shape[0] - 1
    return float(np.linalg.norm(np.diff(u, axis=0)) / k)


def error_norm(residuals):
    """f_xi(k) (Eq. 14) [m]: (1/k) times the second norm of the k residuals xi_p
    (k, N, 3) of a fitted trend (ResidualTrend.residuals)."""
    xi = np.asarray(residuals, dtype=np.float64)
    return float(np.linalg.norm(xi) / xi.shape[0])


def relative_error(computed, estimated):
    """E_r(u) = ||u - u^|| / ||u|| (Eq. 22) [-], the second (Frobenius) norm over the
    N x 3 matrices of the computed and estimated residual displacements."""
    u = np.asarray(computed, dtype=np.float64)
    return float(np.linalg.norm(u - np.asarray(estimated, dtype=np.float64)) / np.linalg.norm(u))


def chernoff_probability(k, epsilon, low, high):
    """The bound 2 exp(-2 k eps^2 / (b - a)^2) [-] (Eq. 15, Hoeffding) on the
    probability that the mean of k independent errors in [low, high] [m] deviates from
    its expectation by at least ``epsilon`` [m]."""
    if not high > low or not epsilon > 0 or k < 1:
        raise ValueError("need high > low, epsilon > 0 and k >= 1")
    return min(1.0, 2.0 * math.exp(-2.0 * k * epsilon**2 / (high - low) ** 2))


def chernoff_cycles(epsilon, probability, low, high):
    """The least number of cycles k with chernoff_probability(k, ...) <= ``probability``:
    k = ceil((b - a)^2 / (2 eps^2) ln(2 / P)) (Eq. 15); errors in [low, high] [m],
    target error ``epsilon`` [m], probability in (0, 1)."""
    if not high > low or not epsilon > 0 or not 0 < probability < 1:
        raise ValueError("need high > low, epsilon > 0 and 0 < probability < 1")
    k = (high - low) ** 2 / (2.0 * epsilon**2) * math.log(2.0 / probability)
    return max(1, math.ceil(k))
