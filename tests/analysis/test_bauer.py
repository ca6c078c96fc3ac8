"""Bauer's law fits, shared/VALIDATION.md section e: check E1 (Levenberg-Marquardt
recovers (e0, h_s, eta) of noisy synthetic oedometric curves from any start within x3),
check E2 (two-point identification on exact data), honest standard errors, readable
failures, and the power law h_s = a eta^b of Oquendo et al. (Fig. 5).

What 8 points with 0.1% noise can give (Cramer-Rao; the fits' own errors agree, see
test_standard_errors_are_honest): with e0 free, sigma(e0)/e0 depends only on eta and the
ladder's shape: 0.13% at eta = 0.57, and never below 0.1%/sqrt(6) = 0.041% (eta -> inf)
on an 8-point doubling ladder. E1's "e0 within 0.05%" is thus about one standard error
at best and cannot be demanded of a fit; e0 is checked against its reported error
instead. h_s and eta within 0.5% need ladders that reach well into the curve: for the
Guamo sand on 12.5 kPa..1.6 MPa sigma(h_s)/h_s = 3.3% (e0 free) or 2.0% (e0 fixed), for
the stiff set 76% and 15%; on 0.2..25.6 MPa with e0 fixed the Guamo sand gives 0.12%,
and the soft set 0.11% on 12.5 kPa..1.6 MPa with e0 free.
"""
import itertools
import json

import numpy as np
import pytest
from scipy.optimize import curve_fit

from graindyn.analysis.bauer import (BauerFitError, bauer, compression, compression_index,
                                     fit_bauer, fit_power_law, two_point)

# (e0, h_s [Pa], eta): the Guamo sand experiment of Oquendo et al. (Sec. 4) and their
# grains of stiffness V = 0.1125 GPa (soft) and 18 GPa (stiff) (Table 2)
GUAMO = (0.80, 19.1e6, 0.57)
SOFT = (0.90, 0.6e6, 1.0)
STIFF = (0.65, 1e10, 0.25)
LADDER = 12.5e3 * 2.0 ** np.arange(8)           # 12.5 kPa .. 1.6 MPa
HIGH_LADDER = 200e3 * 2.0 ** np.arange(8)       # 0.2 .. 25.6 MPa
NOISE = 1e-3                                     # relative, Gaussian


def noisy(params, p, rng):
    return bauer(p, *params) * (1 + NOISE * rng.standard_normal(p.size))


def starts(params):
    """The automatic guess (None) and (h_s, eta) guesses on the edges of the x3 box."""
    _, h_s, eta = params
    return [None] + [(h_s * a, eta * b) for a, b in itertools.product((1 / 3, 1, 3), repeat=2)
                     if (a, b) != (1, 1)]


def relative_errors(fit, params):
    return np.abs(np.array([fit.e0, fit.h_s, fit.eta]) / params - 1)


@pytest.mark.parametrize("params", [GUAMO, SOFT, STIFF], ids=["guamo", "soft", "stiff"])
@pytest.mark.parametrize("e0_fixed", [False, True], ids=["e0_free", "e0_fixed"])
def test_e1_exact_curve_from_any_start(params, e0_fixed):
    """E1, optimizer part: without noise every start within x3 finds the truth."""
    e = bauer(LADDER, *params)
    for guess in starts(params):
        fit = fit_bauer(LADDER, e, e0=params[0] if e0_fixed else None, guess=guess)
        assert np.all(relative_errors(fit, params) < 1e-6), guess


@pytest.mark.parametrize("params, p, e0_fixed", [(SOFT, LADDER, False), (SOFT, LADDER, True),
                                                 (GUAMO, HIGH_LADDER, True)],
                         ids=["soft", "soft_e0_fixed", "guamo_high_e0_fixed"])
def test_e1_noisy_curve_within_tolerance(params, p, e0_fixed):
    """E1 with 0.1% noise where the data hold the information: h_s and eta within 0.5%
    from every start; e0, when free, within 3 of its reported errors (see top)."""
    e = noisy(params, p, np.random.default_rng(11))
    fits = [fit_bauer(p, e, e0=params[0] if e0_fixed else None, guess=guess)
            for guess in starts(params)]
    reference = fits[0]
    assert 3 * reference.h_s_err < 0.005 * params[1] and 3 * reference.eta_err < 0.005 * params[2]
    for fit in fits:
        assert np.all(relative_errors(fit, params)[1:] < 0.005)
        assert abs(fit.e0 - params[0]) <= 3 * reference.e0_err
        assert np.allclose([fit.e0, fit.h_s, fit.eta],
                           [reference.e0, reference.h_s, reference.eta], rtol=1e-6, atol=0)


@pytest.mark.parametrize("params, e0_fixed", [(GUAMO, False), (GUAMO, True), (STIFF, False),
                                              (STIFF, True)],
                         ids=["guamo", "guamo_e0_fixed", "stiff", "stiff_e0_fixed"])
def test_e1_tolerance_is_below_one_error_on_low_ladder(params, e0_fixed):
    """On 12.5 kPa..1.6 MPa one standard error of h_s exceeds E1's 0.5%: these data
    cannot pin h_s that well (the errors are honest: test_standard_errors_are_honest)."""
    e = noisy(params, LADDER, np.random.default_rng(12))
    fit = fit_bauer(LADDER, e, e0=params[0] if e0_fixed else None)
    assert fit.h_s_err > 0.005 * fit.h_s


@pytest.mark.parametrize("params, p, e0_fixed", [(GUAMO, LADDER, False), (SOFT, LADDER, False),
                                                 (GUAMO, HIGH_LADDER, True),
                                                 (STIFF, LADDER, True)],
                         ids=["guamo", "soft", "guamo_high_e0_fixed", "stiff_e0_fixed"])
def test_standard_errors_are_honest(params, p, e0_fixed):
    """Over 200 noise realizations the spread of each fitted parameter matches the mean
    reported standard error within 30%."""
    rng = np.random.default_rng(2024)
    fits = [fit_bauer(p, noisy(params, p, rng), e0=params[0] if e0_fixed else None)
            for _ in range(200)]
    for name in ("h_s", "eta") if e0_fixed else ("e0", "h_s", "eta"):
        spread = np.std([getattr(f, name) for f in fits], ddof=1)
        reported = np.mean([getattr(f, name + "_err") for f in fits])
        assert 1 / 1.3 < spread / reported < 1.3, name


@pytest.mark.parametrize("e0_fixed", [False, True], ids=["e0_free", "e0_fixed"])
def test_covariance_is_curve_fits(e0_fixed):
    """Same optimum and covariance as scipy's curve_fit (absolute_sigma=False) on
    ln e = ln bauer(p; e0, h_s, eta) in the plain parameters."""
    e = noisy(GUAMO, LADDER, np.random.default_rng(13))
    fit = fit_bauer(LADDER, e, e0=GUAMO[0] if e0_fixed else None)
    if e0_fixed:
        popt, pcov = curve_fit(lambda p, h_s, eta: np.log(bauer(p, GUAMO[0], h_s, eta)),
                               LADDER, np.log(e), p0=(fit.h_s, fit.eta), method="lm")
        assert np.all(fit.covariance[0] == 0) and np.all(fit.covariance[:, 0] == 0)
        covariance = fit.covariance[1:, 1:]
    else:
        popt, pcov = curve_fit(lambda p, *q: np.log(bauer(p, *q)), LADDER, np.log(e),
                               p0=(fit.e0, fit.h_s, fit.eta), method="lm")
        covariance = fit.covariance
    assert np.allclose(popt, [fit.h_s, fit.eta] if e0_fixed else [fit.e0, fit.h_s, fit.eta],
                       rtol=1e-6, atol=0)
    assert np.allclose(covariance, pcov, rtol=1e-3, atol=0)


def test_report():
    e = noisy(SOFT, LADDER, np.random.default_rng(14))
    fit = fit_bauer(LADDER, e, pressure="trace")
    record = json.loads(json.dumps(fit.as_dict()))
    assert list(record) == ["pressure", "e0", "e0_err", "e0_fixed", "h_s_Pa", "h_s_err_Pa",
                            "eta", "eta_err", "rms", "points"]
    assert record["pressure"] == "trace" and record["points"] == 8 and not record["e0_fixed"]
    assert record["h_s_Pa"] == fit.h_s and record["eta_err"] == fit.eta_err
    assert np.allclose(np.sqrt(np.diag(fit.covariance)), [fit.e0_err, fit.h_s_err, fit.eta_err])
    assert np.allclose(fit.curve(LADDER), bauer(LADDER, fit.e0, fit.h_s, fit.eta))
    assert fit.rms == pytest.approx(np.sqrt(np.mean(np.log(e / fit.curve(LADDER)) ** 2)))
    fixed = fit_bauer(LADDER, e, e0=SOFT[0])
    assert fixed.e0 == SOFT[0] and fixed.e0_err == 0.0 and fixed.as_dict()["e0_fixed"]


def exact_compression_index(p, params):
    """C_c = -de/d ln p = eta e (p/h_s)^eta, differentiated by hand."""
    _, h_s, eta = params
    return eta * bauer(p, *params) * (p / h_s) ** eta


@pytest.mark.parametrize("params", [GUAMO, SOFT, STIFF], ids=["guamo", "soft", "stiff"])
@pytest.mark.parametrize("i, j", [(0, 7), (2, 3), (6, 1)])
def test_e2_two_point_on_exact_data(params, i, j):
    e = bauer(LADDER, *params)
    cc = exact_compression_index(LADDER, params)
    h_s, eta = two_point(LADDER[i], e[i], cc[i], LADDER[j], e[j], cc[j])
    assert h_s == pytest.approx(params[1], rel=1e-6) and eta == pytest.approx(params[2], rel=1e-6)


def test_compression_index_is_second_order():
    """Halving the step in ln p divides the largest error (ends included) by 4."""
    errors = []
    for ratio in (2.0, np.sqrt(2.0)):
        p = 12.5e3 * ratio ** np.arange(round(7 * np.log(2) / np.log(ratio)) + 1)
        error = compression_index(p, bauer(p, *GUAMO)) - exact_compression_index(p, GUAMO)
        errors.append(np.max(np.abs(error)))
    assert 1.8 < np.log2(errors[0] / errors[1]) < 2.2


E = bauer(LADDER, *GUAMO)


@pytest.mark.parametrize("call, message", [
    (lambda: fit_bauer(LADDER[:3], E[:3]),
     r"fitting \(e0, h_s, eta\) needs at least 4 points, got 3"),
    (lambda: fit_bauer(LADDER[:2], E[:2], e0=0.8), r"needs at least 3 points, got 2"),
    (lambda: fit_bauer(LADDER, np.r_[E[:4], 1.001 * E[3], E[5:]]),
     r"void ratio must decrease strictly .* between points 3->4"),
    (lambda: fit_bauer(np.r_[0.0, LADDER[1:]], E), r"pressure is <= 0 at points \[0\]"),
    (lambda: fit_bauer(LADDER, np.r_[E[:2], np.nan, E[3:]]),
     r"void ratio is not finite at points \[2\]"),
    (lambda: fit_bauer(LADDER, np.r_[E[:5], -0.1, E[6:]]), r"void ratio is <= 0 at points \[5\]"),
    (lambda: fit_bauer(LADDER[::-1], E), r"pressure must increase strictly"),
    (lambda: fit_bauer(LADDER, E, e0=0.9 * E[0]), r"e0 = .* must be finite and above"),
    (lambda: fit_bauer(LADDER, E, guess=(1.0, 1e3)), r"starting guess overflows"),
    (lambda: fit_bauer(LADDER, E, guess=(0.8, 19.1e6, 0.57)), r"guess \(h_s, eta\) needs 2 values"),
    (lambda: fit_bauer(LADDER[:6], [1.0, 0.5, 0.49, 0.48, 0.47, 0.46]),
     r"singular covariance|runs off|did not converge"),
    (lambda: two_point(1e5, 0.7, 0.01, 1e5, 0.6, 0.02), r"two different pressures"),
    (lambda: two_point(1e5, 0.7, 0.01, 2e5, 0.6, 0.001), r"eta = .* <= 0"),
    (lambda: fit_power_law([0.3, 0.5], [10.0, 1.0]), r"needs at least 3 points, got 2"),
    (lambda: fit_power_law([0.3, 0.5, 0.6], [10.0, 0.0, 1.0]), r"y is <= 0 at points \[1\]"),
], ids=["too_few", "too_few_e0_fixed", "not_decreasing", "p_zero", "nan", "e_negative",
        "unloading", "e0_below_data", "overflowing_guess", "guess_length", "degenerate",
        "same_pressure", "not_bauer", "power_too_few", "power_y_zero"])
def test_unfittable_data_raise_one_line(call, message):
    with pytest.raises(BauerFitError, match=message) as error:
        call()
    assert "\n" not in str(error.value)


# eta of the runs in Oquendo et al., Tables 2 and 3
ETAS = np.array([1.1, 1.0, 0.51, 0.24, 0.428, 0.302, 0.26, 0.40, 0.287, 0.29, 0.32, 0.27,
                 0.26, 0.20, 0.30, 0.19, 0.23])


def test_power_law_exact():
    fit = fit_power_law(ETAS, 0.068 * ETAS ** -9.88)
    assert fit.a == pytest.approx(0.068, rel=1e-10) and fit.b == pytest.approx(-9.88, rel=1e-10)
    assert fit.as_dict() == {"a": fit.a, "a_err": fit.a_err, "b": fit.b, "b_err": fit.b_err,
                             "points": ETAS.size}


def test_power_law_weighted_errors_are_honest():
    """Log-normal scatter of 5..40%, given as y_err proportional to the measured y (as
    fits report it): over 200 realizations the fit is unbiased in ln a and b, and its
    reported errors match the spread within 30%."""
    rng = np.random.default_rng(15)
    relative = np.linspace(0.05, 0.4, ETAS.size)
    fits = []
    for _ in range(200):
        y = 0.068 * ETAS ** -9.88 * np.exp(relative * rng.standard_normal(ETAS.size))
        fits.append(fit_power_law(ETAS, y, relative * y))
    a = np.array([f.a for f in fits])
    b = np.array([f.b for f in fits])
    for unbiased, truth in ((np.log(a), np.log(0.068)), (b, -9.88)):
        assert abs(np.mean(unbiased) - truth) < 3 * np.std(unbiased) / np.sqrt(len(fits))
    for values, errors in ((a, [f.a_err for f in fits]), (b, [f.b_err for f in fits])):
        assert 1 / 1.3 < np.std(values, ddof=1) / np.mean(errors) < 1.3


def test_equal_compression_gives_a_steep_power_law():
    """Bauer curves through one compression c = 0.08 at p = 3.2 MPa, eta from 0.2 to
    0.3: compression() reads c back, the curves meet there, and their (eta, h_s) follow
    a power law whose exponent is ln(c)/eta at the middle of the range (-10.1), within
    5 %; a family of twice the compression gives an exponent 27 % less steep."""
    p = 3.2e6
    eta = np.linspace(0.2, 0.3, 11)
    for c, slope in ((0.08, np.log(0.08) / 0.25), (0.16, np.log(0.16) / 0.25)):
        h_s = p * c ** (-1.0 / eta)
        assert compression(p, h_s, eta) == pytest.approx(np.full(11, c), rel=1e-12)
        assert bauer(p, 0.9, h_s, eta) == pytest.approx(np.full(11, 0.9 * np.exp(-c)))
        fit = fit_power_law(eta, h_s)
        assert fit.b == pytest.approx(slope, rel=0.05)
    assert np.log(0.16) / np.log(0.08) == pytest.approx(0.73, abs=0.01)
