"""Bauer's compression law and its calibration from an oedometric test:

    e/e0 = exp[-(p/h_s)^eta]                          (Oquendo et al., Eq. 19)

e the void ratio [-], e0 its value before loading [-], p the pressure [Pa], h_s the
granular hardness [Pa], eta the exponent [-]. Bauer (1996, Soils Found. 36:13) and Herle &
Gudehus (1999, MCFM 4:461) take p = tr sigma = 3 p_s; against the oedometer's vertical
stress sigma_v = tr sigma/(1 + 2 K0) the same data give the same eta and h_s/(1 + 2 K0)
(shared/VALIDATION.md e). A fit records which one it used in ``pressure``: "trace" or
"vertical".

Two-point identification (VALIDATION.md e), with C_c = -de/d ln p:

    eta = ln[(e1 C_c2)/(e2 C_c1)] / ln(p2/p1),      h_s = p (eta e/C_c)^(1/eta).

Oquendo et al. (Fig. 5) relate the two parameters by a power law, h_s = 0.068(4)
eta^-9.88(3) with h_s in MPa; ``fit_power_law`` fits y = a x^b.

Oquendo, Munoz & Lizcano, "Oedometric test, Bauer's law and the micro-macro connection
for a dry sand" (shared/seeds/oquendo-oedometric-bauer.txt).
"""
import dataclasses

import numpy as np
from scipy.optimize import least_squares


class BauerFitError(ValueError):
    """Data that cannot be fitted; the message says why in one line."""


def bauer(p, e0, h_s, eta):
    """Void ratio [-] at pressures p [Pa] (array-like), Eq. 19."""
    return e0 * np.exp(-(np.asarray(p, float) / h_s) ** eta)


@dataclasses.dataclass(frozen=True, eq=False)   # eq=False: an array has no truth value
class BauerFit:
    """Fitted (e0, h_s, eta) with standard errors from the covariance, scaled by the
    residual variance (as curve_fit with absolute_sigma=False).

    covariance : (3, 3) float64 in the order (e0 [-], h_s [Pa], eta [-]); the e0 row and
    column are zero when e0 was fixed. rms [-]: root mean square of ln(e/e_fit), the
    relative misfit that the fit minimizes. points: number of data points.
    """
    e0: float
    e0_err: float
    h_s: float
    h_s_err: float
    eta: float
    eta_err: float
    covariance: np.ndarray
    rms: float
    points: int
    e0_fixed: bool
    pressure: str

    def curve(self, p):
        """The fitted law at pressures p [Pa]."""
        return bauer(p, self.e0, self.h_s, self.eta)

    def as_dict(self):
        """JSON-able record; other code reads these keys."""
        return {"pressure": self.pressure, "e0": float(self.e0), "e0_err": float(self.e0_err),
                "e0_fixed": bool(self.e0_fixed), "h_s_Pa": float(self.h_s),
                "h_s_err_Pa": float(self.h_s_err), "eta": float(self.eta),
                "eta_err": float(self.eta_err), "rms": float(self.rms),
                "points": int(self.points)}


@dataclasses.dataclass(frozen=True)
class PowerLawFit:
    """y = a x^b; a in the units of y, standard errors scaled by the residual variance."""
    a: float
    a_err: float
    b: float
    b_err: float
    points: int

    def as_dict(self):
        return {"a": float(self.a), "a_err": float(self.a_err), "b": float(self.b),
                "b_err": float(self.b_err), "points": int(self.points)}


def _positive(name, values):
    """values as a 1-D float array of finite, positive entries."""
    values = np.atleast_1d(np.asarray(values, float))
    if values.ndim != 1:
        raise BauerFitError(f"{name} must be a 1-D sequence, got shape {values.shape}")
    for bad, what in ((~np.isfinite(values), "is not finite"), (values <= 0, "is <= 0")):
        if bad.any():
            raise BauerFitError(f"{name} {what} at points {np.flatnonzero(bad).tolist()}")
    return values


def _loading_curve(p, e, minimum, purpose):
    """(p, e) checked to be one loading branch of at least ``minimum`` points: p rising
    and e falling strictly."""
    p, e = _positive("pressure", p), _positive("void ratio", e)
    if p.size != e.size:
        raise BauerFitError(f"{p.size} pressures but {e.size} void ratios")
    if p.size < minimum:
        raise BauerFitError(f"{purpose} needs at least {minimum} points, got {p.size}")
    for values, name, trend, fails in ((p, "pressure", "increase", np.diff(p) <= 0),
                                       (e, "void ratio", "decrease", np.diff(e) >= 0)):
        if fails.any():
            steps = ", ".join(f"{i}->{i + 1} ({values[i]:.6g} -> {values[i + 1]:.6g})"
                              for i in np.flatnonzero(fails))
            raise BauerFitError(f"{name} must {trend} strictly along the loading; "
                                f"it does not between points {steps}")
    return p, e


def _scaled_covariance(jacobian, residuals):
    """Parameter covariance s^2 (J^T J)^-1 with s^2 = sum r^2/(n - k), by SVD."""
    _, s, vt = np.linalg.svd(jacobian, full_matrices=False)
    if s[-1] <= np.finfo(float).eps * max(jacobian.shape) * s[0]:
        raise BauerFitError("singular covariance: the points do not determine all the "
                            "parameters")
    dof = jacobian.shape[0] - jacobian.shape[1]
    return (vt.T / s**2) @ vt * (residuals @ residuals / dof)


def compression_index(p, e):
    """C_c = -de/d ln p [-] at each point: second-order finite differences in ln p,
    one-sided at the ends."""
    p, e = _loading_curve(p, e, 3, "compression_index")
    return -np.gradient(e, np.log(p), edge_order=2)


def two_point(p1, e1, cc1, p2, e2, cc2):
    """(h_s [Pa], eta) from the void ratios and compression indices at two pressures [Pa];
    h_s is the geometric mean of the two points' values (equal on exact data)."""
    p1, e1, cc1, p2, e2, cc2 = _positive("two-point input (p1, e1, cc1, p2, e2, cc2)",
                                         (p1, e1, cc1, p2, e2, cc2))
    if p1 == p2:
        raise BauerFitError("two-point identification needs two different pressures")
    eta = np.log(e1 * cc2 / (e2 * cc1)) / np.log(p2 / p1)
    if not eta > 0:
        raise BauerFitError(f"the two points give eta = {eta:.6g} <= 0: they do not follow "
                            "Bauer's law")
    h_s = np.sqrt(p1 * p2) * (eta * eta * e1 * e2 / (cc1 * cc2)) ** (0.5 / eta)
    return float(h_s), float(eta)


def _linearized(u, e, e0):
    """(ln x_ref, eta) of ln(-ln(e/e0)) = ln x_ref + eta u, u = ln(p/p_ref), weighted by
    -ln(e/e0) so that each point counts as its misfit in ln e does."""
    x = -np.log(e / e0)
    eta, ln_x_ref = np.polyfit(u, np.log(x), 1, w=x)
    return ln_x_ref, eta


def _automatic_guess(u, e, e0):
    """Starting (ln x_ref, ln eta) from the linearization. A free e0 is scanned from just
    above e[0] to 20 e[0], keeping the value whose linearized fit leaves the smallest
    misfit in ln e."""
    best = (np.inf, None)
    candidates = [e0] if e0 is not None else e[0] * np.exp(np.geomspace(1e-6, 3.0, 64))
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        for trial in candidates:
            ln_x_ref, eta = _linearized(u, e, trial)
            misfit = np.sum((np.log(e / trial) + np.exp(ln_x_ref + eta * u)) ** 2)
            if eta > 0 and misfit < best[0]:
                best = (misfit, (ln_x_ref, np.log(eta)))
    if best[1] is None:
        raise BauerFitError("the linearization gives no starting point; pass guess=(h_s, eta)")
    return np.array(best[1])


def fit_bauer(p, e, e0=None, pressure="vertical", guess=None):
    """Fit Eq. 19 to an oedometric loading curve by Levenberg-Marquardt.

    p : (N,) pressures [Pa], strictly increasing; e : (N,) void ratios [-], strictly
    decreasing. e0: the void ratio before loading, if measured; None fits it too, and
    then N >= 4 (N >= 3 otherwise). pressure: what p is, "vertical" (sigma_v) or "trace"
    (tr sigma). guess: starting (h_s [Pa], eta), by default from the linearization.

    Minimizes sum ln(e/e_fit)^2 over (ln x_ref, ln eta), x_ref = (p_ref/h_s)^eta at the
    geometric-mean pressure, where the two are far less correlated than h_s and eta. A
    free ln e0 enters linearly and is solved exactly at every step (variable projection,
    Golub & Pereyra 1973, SIAM J. Numer. Anal. 10:413), so it needs no start; the
    covariance is that of all the fitted parameters, from the full Jacobian at the optimum.
    """
    if not isinstance(pressure, str) or not pressure:
        raise BauerFitError(f"pressure must be a non-empty label, got {pressure!r}")
    free = 2 if e0 is not None else 3
    p, e = _loading_curve(p, e, free + 1,
                          "fitting (h_s, eta)" if e0 is not None else "fitting (e0, h_s, eta)")
    if e0 is not None and not (np.isfinite(e0) and e0 > e[0]):
        raise BauerFitError(f"e0 = {e0} must be finite and above the first void ratio "
                            f"under load, e[0] = {e[0]:.6g}")
    ln_p_ref = np.mean(np.log(p))
    u = np.log(p) - ln_p_ref
    ln_e = np.log(e)
    if guess is None:
        q0 = _automatic_guess(u, e, e0)
    else:
        guess = _positive("guess (h_s, eta)", guess)
        if guess.size != 2:
            raise BauerFitError(f"guess (h_s, eta) needs 2 values, got {guess.size}")
        q0 = np.array([guess[1] * (ln_p_ref - np.log(guess[0])), np.log(guess[1])])

    def columns(q):
        """d ln e_fit/d(ln x_ref, ln eta), negated: the Jacobian of ln e - ln e_fit."""
        eta = np.exp(q[1])
        x = np.exp(q[0] + eta * u)
        return np.column_stack((x, x * eta * u))

    def residuals(q):
        """ln e - ln e_fit; with e0 free, ln e0 = mean(ln e + x) taken out term by term
        so that a huge x cannot swamp ln e."""
        x = columns(q)[:, 0]
        if e0 is not None:
            return ln_e - np.log(e0) + x
        return (ln_e - ln_e.mean()) + (x - x.mean())

    def jacobian(q):
        jac = columns(q)
        return jac if e0 is not None else jac - jac.mean(axis=0)

    with np.errstate(over="ignore", invalid="ignore"):
        if not np.all(np.isfinite(residuals(q0))):
            raise BauerFitError("the starting guess overflows the law at these pressures")
        result = least_squares(residuals, q0, jac=jacobian, method="lm", xtol=1e-12,
                               ftol=1e-12, gtol=1e-12)
    if result.status <= 0:
        raise BauerFitError(f"Levenberg-Marquardt did not converge: {result.message}")
    if not np.all(np.isfinite(result.x)):
        raise BauerFitError("Levenberg-Marquardt ran off to non-finite parameters")
    full = columns(result.x)
    if e0 is None:
        full = np.column_stack((-np.ones(p.size), full))
    internal = _scaled_covariance(full, result.fun)
    c, eta = result.x[0], np.exp(result.x[1])
    with np.errstate(over="ignore"):
        h_s = np.exp(ln_p_ref - c / eta)
        fitted_e0 = e0 if e0 is not None else np.exp(np.mean(ln_e + full[:, -2]))
    if not (np.isfinite(h_s) and h_s > 0 and np.isfinite(fitted_e0)):
        raise BauerFitError(f"the best fit runs off to eta = {eta:.3g}, h_s = {h_s:.3g} Pa, "
                            f"e0 = {fitted_e0:.3g}: the points do not follow Bauer's law")
    # d(e0, h_s, eta)/d(ln e0, ln x_ref, ln eta): the covariance maps through it exactly
    transform = np.array([[fitted_e0, 0.0, 0.0],
                          [0.0, -h_s / eta, h_s * c / eta],
                          [0.0, 0.0, eta]])[:, 3 - free:]
    covariance = transform @ internal @ transform.T
    errors = np.sqrt(np.diag(covariance))
    return BauerFit(e0=float(fitted_e0), e0_err=float(errors[0]), h_s=float(h_s),
                    h_s_err=float(errors[1]), eta=float(eta), eta_err=float(errors[2]),
                    covariance=covariance, rms=float(np.sqrt(np.mean(result.fun**2))),
                    points=p.size, e0_fixed=e0 is not None, pressure=pressure)


def compression(p, h_s, eta):
    """ln(e0/e) = (p/h_s)^eta [-], the compression a Bauer curve (Eq. 19) gives at
    pressures p [Pa].  Inverted, h_s = p c^(-1/eta): Bauer curves through one
    compression c at one pressure p differ in h_s by c^(-1/eta), so fits of samples that
    compress alike scatter along d ln h_s / d ln eta = ln(c)/eta, a power law of
    exponent -10 for c = 0.08 near eta = 0.25 (docs/oedometer.md)."""
    return (np.asarray(p, float) / h_s) ** eta


def fit_power_law(x, y, y_err=None):
    """Fit y = a x^b by weighted linear least squares of ln y on ln x, each point
    weighted by (y/y_err)^2 when y_err is given (equal weights otherwise)."""
    x, y = _positive("x", x), _positive("y", y)
    sigma = np.ones_like(y) if y_err is None else _positive("y_err", y_err) / y
    if not x.size == y.size == sigma.size:
        raise BauerFitError(f"x, y and y_err differ in length: {x.size}, {y.size}, "
                            f"{sigma.size}")
    if x.size < 3:
        raise BauerFitError(f"fitting (a, b) needs at least 3 points, got {x.size}")
    design = np.column_stack((np.ones_like(x), np.log(x))) / sigma[:, None]
    target = np.log(y) / sigma
    (ln_a, b), *_ = np.linalg.lstsq(design, target, rcond=None)
    covariance = _scaled_covariance(design, target - design @ (ln_a, b))
    a = np.exp(ln_a)
    return PowerLawFit(a=float(a), a_err=float(a * np.sqrt(covariance[0, 0])), b=float(b),
                       b_err=float(np.sqrt(covariance[1, 1])), points=x.size)
