"""Estimation and extrapolation of residual displacements (Karrech Eq. 13-22) on
synthetic data with known linear and logarithmic trends."""
import math

import numpy as np
import pytest

from graindyn.analysis.settlement import (chernoff_cycles, chernoff_probability, error_norm,
                                          fit_residual, forecast_errors, increment_norm,
                                          lstsq_shared, relative_error, smooth_increments)

N = 50                     # grains
PERIOD = 0.02              # [s], 50 Hz


def _times(k, start=0.2):
    return start + PERIOD * np.arange(k + 1)          # t_0 = start, t_p = start + p T


def _shenton(rng, times, noise):
    """u = a ln t + b t per grain and component, plus white noise [m]."""
    a = rng.uniform(1e-6, 5e-6, (N, 3))
    b = rng.uniform(1e-6, 5e-6, (N, 3))
    u = np.log(times)[:, None, None] * a + times[:, None, None] * b
    return u + noise * rng.standard_normal(u.shape), a, b


def _linear(rng, times, noise):
    """u = s (t - t_0) per grain and component, plus white noise [m]."""
    s = rng.uniform(-5e-5, 5e-5, (N, 3))
    u = (times - times[0])[:, None, None] * s
    return u + noise * rng.standard_normal(u.shape), s


def test_shenton_parameters_and_extrapolation_recovered(rng):
    t = _times(40)
    u, a, b = _shenton(rng, t, 0.0)
    fit = fit_residual(u, t, "shenton")
    assert np.allclose(fit.coefficients[0], a, rtol=1e-9)
    assert np.allclose(fit.coefficients[1], b, rtol=1e-9)
    target = t[-1] + 40 * PERIOD
    exact = np.log(target) * a + target * b
    assert np.allclose(fit.extrapolate_cycles(40), exact, rtol=1e-9, atol=1e-15)
    # with white noise of 1e-8 m, about 6 % of a cycle's increment (measured: a, b
    # within 0.09 %, the extrapolation within 0.15 %): within 1 % (E_r)
    u, a, b = _shenton(rng, t, 1e-8)
    fit = fit_residual(u, t, "shenton")
    assert relative_error(a, fit.coefficients[0]) < 0.01
    assert relative_error(b, fit.coefficients[1]) < 0.01
    assert relative_error(np.log(target) * a + target * b, fit.extrapolate(target)) < 0.01


def test_shenton_intercept_removes_the_reference(rng):
    """Displacements measured from the window start (u_0 = 0) after 500 initial cycles:
    the fit with an intercept recovers a and b, the paper's fit without it cannot."""
    t = _times(40, start=10.0)
    u, a, b = _shenton(rng, t, 0.0)
    u = u - u[0]
    with_c = fit_residual(u, t, "shenton", intercept=True)
    assert np.allclose(with_c.coefficients[1], a, rtol=1e-6)
    assert np.allclose(with_c.coefficients[2], b, rtol=1e-6)
    target = t[-1] + 40 * PERIOD
    exact = np.log(target) * a + target * b - (np.log(t[0]) * a + t[0] * b)
    assert relative_error(exact, with_c.extrapolate(target)) < 1e-8
    assert relative_error(exact, fit_residual(u, t, "shenton").extrapolate(target)) > 1e-3


def test_linear_parameters_and_extrapolation_recovered(rng):
    t = _times(40)
    u, s = _linear(rng, t, 0.0)
    fit = fit_residual(u, t, "linear")
    assert np.allclose(fit.coefficients[0], s, rtol=1e-12)
    assert np.allclose(fit.extrapolate_cycles(20), u[-1] + 20 * PERIOD * s, rtol=1e-12)
    # Eq. 16 literally: u_k + h/k sum of the increments
    h, k = 20, 40
    eq16 = u[-1] + h / k * np.diff(u, axis=0).sum(axis=0)
    assert np.allclose(fit.extrapolate_cycles(h), eq16, rtol=1e-12)


def test_each_estimator_wins_on_its_own_law(rng):
    t = _times(40)
    target = t[-1] + 40 * PERIOD
    u, a, b = _shenton(rng, t, 1e-9)
    exact = np.log(target) * a + target * b
    log_error = relative_error(exact, fit_residual(u, t, "shenton").extrapolate(target))
    lin_error = relative_error(exact, fit_residual(u, t, "linear").extrapolate(target))
    assert log_error < 0.01 < lin_error and log_error < lin_error / 5
    u, s = _linear(rng, t, 2e-8)
    exact = (target - t[0]) * s
    log_error = relative_error(exact, fit_residual(u, t, "shenton").extrapolate(target))
    lin_error = relative_error(exact, fit_residual(u, t, "linear").extrapolate(target))
    assert lin_error < 0.01 and lin_error < log_error / 5


def _logarithmic(rng, times, noise):
    """u = c + a ln t per grain and component, plus white noise [m]."""
    c = rng.uniform(-1e-5, 1e-5, (N, 3))
    a = rng.uniform(1e-6, 5e-6, (N, 3))
    return c + np.log(times)[:, None, None] * a + noise * rng.standard_normal(
        (times.size, N, 3)), c, a


def test_logarithmic_parameters_and_extrapolation_recovered(rng):
    """A window of 10 cycles after 500 (t from 10 s at 50 Hz), displacements measured
    from its start: c and a recovered, and the jump of 80 cycles is a ln(1 + h / t_k)
    exactly, where Eq. 16 carries the window's mean rate a ln(t_k / t_0) / (t_k - t_0)
    on over the h T of the jump: by hand, 0.099013 x 1.6 s = 0.158421 against
    ln(11.8 / 10.2) = 0.145712 (times a), 8.72 % too far."""
    t = _times(10, start=10.0)
    u, c, a = _logarithmic(rng, t, 0.0)
    u = u - u[0]
    fit = fit_residual(u, t, "logarithmic")
    assert fit.intercept and fit.coefficients.shape == (2, N, 3)
    assert np.allclose(fit.coefficients[1], a, rtol=1e-7)
    assert np.allclose(fit.coefficients[0], -np.log(t[0]) * a, rtol=1e-7)
    target = t[-1] + 80 * PERIOD
    jump = a * np.log(target / t[-1])
    assert relative_error(jump, fit.extrapolate(target) - u[-1]) < 1e-9
    linear = fit_residual(u, t, "linear").extrapolate(target) - u[-1]
    rate = a * np.log(t[-1] / t[0]) / (t[-1] - t[0])
    assert np.allclose(linear, rate * (target - t[-1]), rtol=1e-12)
    overshoot = np.log(t[-1] / t[0]) / (t[-1] - t[0]) * (target - t[-1]) \
        / np.log(target / t[-1]) - 1.0
    assert 0.0871 < overshoot < 0.0873
    assert np.allclose(linear / jump - 1.0, overshoot, rtol=1e-9)


def test_the_logarithmic_law_wins_on_its_own_trend_and_loses_on_a_steady_one(rng):
    """With noise of 2 % of a cycle's increment, on a logarithmic trend the logarithmic
    law extrapolates 80 cycles within 1 % and Eq. 16 misses by more than 5 %; on a
    steady trend the reverse."""
    t = _times(20, start=10.0)
    target = t[-1] + 80 * PERIOD
    u, c, a = _logarithmic(rng, t, 2e-10)
    exact = c + np.log(target) * a
    log_error = relative_error(exact - u[-1], fit_residual(u, t, "logarithmic")
                               .extrapolate(target) - u[-1])
    lin_error = relative_error(exact - u[-1], fit_residual(u, t, "linear")
                               .extrapolate(target) - u[-1])
    assert log_error < 0.01 and lin_error > 0.05
    u, s = _linear(rng, t, 1e-10)
    exact = (target - t[0]) * s
    log_error = relative_error(exact - u[-1], fit_residual(u, t, "logarithmic")
                               .extrapolate(target) - u[-1])
    lin_error = relative_error(exact - u[-1], fit_residual(u, t, "linear")
                               .extrapolate(target) - u[-1])
    assert lin_error < 0.01 and log_error > 0.05


def test_lstsq_shared_matches_a_per_column_solve(rng):
    t = 100.0 + PERIOD * np.arange(1, 41)         # ill-conditioned: cond ~ 2e8
    design = np.stack([np.ones_like(t), np.log(t), t], axis=1)
    truth = rng.standard_normal((3, 7, 3))
    values = np.einsum("tm,mnd->tnd", design, truth)
    assert np.allclose(lstsq_shared(design, values), truth, rtol=1e-5, atol=1e-5)
    reference = np.linalg.lstsq(design, values.reshape(40, -1), rcond=None)[0]
    assert np.allclose(lstsq_shared(design, values).reshape(3, -1), reference,
                       rtol=1e-6, atol=1e-6)


def test_error_measures_by_hand():
    # two grains, k = 2 cycles: increments (1, 0, 0), (0, 2, 0) | (0, 0, 2), (0, 0, 0)
    u = np.zeros((3, 2, 3))
    u[1, 0] = (1, 0, 0)
    u[2, 0] = (1, 2, 0)
    u[1, 1] = (0, 0, 2)
    u[2, 1] = (0, 0, 2)
    assert increment_norm(u) == pytest.approx(math.sqrt(1 + 4 + 4) / 2)
    xi = np.zeros((2, 2, 3))
    xi[0, 0, 0] = 3.0
    xi[1, 1, 2] = 4.0
    assert error_norm(xi) == pytest.approx(5.0 / 2)
    computed = np.array([[3.0, 0, 0], [0, 4.0, 0]])
    estimated = np.array([[3.0, 0, 1.0], [0, 4.0, 0]])
    assert relative_error(computed, estimated) == pytest.approx(1.0 / 5.0)
    # the linear trend through u_0 and u_k: residuals at p = 1 only
    fit = fit_residual(u, [0.0, 1.0, 2.0], "linear")
    assert np.allclose(fit.residuals[0, 0], (0.5, -1.0, 0.0))
    assert np.allclose(fit.residuals[1], 0.0)
    assert error_norm(fit.residuals) == pytest.approx(math.sqrt(1.25 + 1.0) / 2)


def test_chernoff_cycles_by_hand_and_monte_carlo(rng):
    # (b - a)^2 / (2 eps^2) ln(2 / P) = 1 / (2 * 0.01) * ln(40) = 184.44 -> 185
    k = chernoff_cycles(0.1, 0.05, -0.5, 0.5)
    assert k == 185
    assert chernoff_probability(k, 0.1, -0.5, 0.5) <= 0.05 < chernoff_probability(
        k - 1, 0.1, -0.5, 0.5)
    # Monte Carlo: means of k zero-mean variables in [a, b] (the worst case of
    # Hoeffding's bound is two-point, +-1/2) deviate by >= eps no more often than P
    trials = 20000
    for draw in (lambda n: rng.uniform(-0.5, 0.5, n), lambda n: rng.choice([-0.5, 0.5], n)):
        means = draw((trials, k)).mean(axis=1)
        frequency = np.mean(np.abs(means) >= 0.1)
        assert frequency <= 0.05
    # and the bound itself is not vacuous: the two-point variable at k = 10, eps = 0.3
    means = rng.choice([-0.5, 0.5], (trials, 10)).mean(axis=1)
    assert np.mean(np.abs(means) >= 0.3) <= chernoff_probability(10, 0.3, -0.5, 0.5) < 1


def test_bad_input_is_rejected():
    with pytest.raises(ValueError):
        fit_residual(np.zeros((3, 2, 3)), [-1.0, 0.0, 1.0], "shenton")      # ln 0
    with pytest.raises(ValueError):
        fit_residual(np.zeros((3, 2, 3)), [1.0, 1.0, 2.0], "linear")        # not increasing
    with pytest.raises(ValueError):
        fit_residual(np.zeros((3, 2, 3)), [1.0, 2.0, 3.0], "power")
    with pytest.raises(ValueError):
        chernoff_cycles(0.1, 1.5, 0.0, 1.0)


def _lattice(n, spacing=1.0):
    """A cubic lattice of n^3 points centred on the origin [m]."""
    axis = spacing * (np.arange(n) - 0.5 * (n - 1))
    return np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), -1).reshape(-1, 3)


def test_smoothing_keeps_an_affine_field_and_averages_noise_away(rng):
    """On a lattice, the Gaussian average of an affine field u = A x + c is the field
    itself at every point whose neighbourhood (3 lengths) is complete, since the
    neighbourhood is symmetric; white noise added to it comes out reduced by about the
    square root of the weights' effective number, sum(w)^2 / sum(w^2)."""
    x = _lattice(15)
    a = rng.normal(size=(3, 3)) * 1e-3
    c = rng.normal(size=3) * 1e-4
    field = x @ a.T + c
    length = 1.0
    inner = np.all(np.abs(x) <= 7 - 3 * length, axis=1)
    smooth = smooth_increments(x, field, length)
    np.testing.assert_allclose(smooth[inner], field[inner], rtol=0, atol=1e-15)
    sigma = 1e-4
    noisy = field + sigma * rng.standard_normal(field.shape)
    error = smooth_increments(x, noisy, length)[inner] - field[inner]
    r = np.linalg.norm(_lattice(7), axis=1)
    w = np.exp(-0.5 * r[r < 3 * length] ** 2 / length**2)
    expected = sigma * np.sqrt(np.sum(w**2)) / np.sum(w)
    assert np.std(error) == pytest.approx(expected, rel=0.1)
    assert np.std(error) < 0.4 * sigma
    np.testing.assert_array_equal(smooth_increments(x, noisy, 0.0), noisy)


def test_the_local_linear_fit_keeps_an_affine_field_up_to_the_boundaries(rng):
    """Grains scattered at random in a box (no lattice symmetry), an affine field u =
    A x + c: fit = "linear" gives the field back at every grain, those at the faces
    and corners included; the mean does only on average far inside (grain by grain it
    errs where the scatter leaves a neighbourhood lopsided), and in the top face's layer
    it pulls a field growing upwards down by more than half its gradient times length
    (at most sqrt(2 / pi) length, the mean offset of a one-sided Gaussian, which a
    grain at the face itself would see).  Noise is averaged away by both."""
    x = rng.uniform(0.0, 20.0, size=(4000, 3))
    a = rng.normal(size=(3, 3)) * 1e-3
    c = rng.normal(size=3) * 1e-4
    field = x @ a.T + c
    length = 1.5
    linear = smooth_increments(x, field, length, fit="linear")
    np.testing.assert_allclose(linear, field, rtol=0, atol=1e-12)
    descent = np.zeros_like(x)
    descent[:, 2] = 1e-3 * x[:, 2]                      # a strain rate of 1e-3 per length
    top = x[:, 2] > 20.0 - 0.2 * length
    inside = np.all((x > 3 * length) & (x < 20.0 - 3 * length), axis=1)
    mean = smooth_increments(x, descent, length)
    assert -1e-3 * np.sqrt(2 / np.pi) * length < np.mean(mean[top, 2] - descent[top, 2]) \
        < -0.5e-3 * length
    assert abs(np.mean(mean[inside, 2] - descent[inside, 2])) < 0.05e-3 * length
    np.testing.assert_allclose(smooth_increments(x, descent, length, fit="linear"),
                               descent, rtol=0, atol=1e-12)
    sigma = 1e-4
    noisy = field + sigma * rng.standard_normal(field.shape)
    error = smooth_increments(x, noisy, length, fit="linear")[inside] - field[inside]
    assert np.std(error) < 0.4 * sigma
    with pytest.raises(ValueError, match="fit must be one of"):
        smooth_increments(x, field, length, fit="median")


@pytest.mark.parametrize("fit", ["mean", "linear"])
def test_a_lone_grain_keeps_its_increment(fit):
    """A grain with no other within 3 lengths keeps its own increment (no gradient can
    be fitted to one point: it is held to zero)."""
    x = np.array([[0.0, 0.0, 0.0], [100.0, 0.0, 0.0]])
    u = np.array([[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]])
    np.testing.assert_allclose(smooth_increments(x, u, 1.0, fit=fit), u, rtol=1e-12)


@pytest.mark.parametrize("fit", ["mean", "linear"])
@pytest.mark.parametrize("axes", [(0,), (0, 1)])
def test_smoothing_across_symmetry_planes_equals_the_whole_bed(rng, axes, fit):
    """Grains on the positive side of the planes x = 0 (and y = 0) with any
    increments: smoothing them with the planes gives, grain by grain, what smoothing
    the whole bed gives, the whole bed being them and their mirror images with the
    normal component of the increments reversed (the corner image through both planes
    included)."""
    x = _lattice(12, spacing=1.1) + 0.05            # no grain on a plane
    x = x[np.all(x[:, list(axes)] > 0, axis=1)]
    u = rng.normal(size=x.shape)
    clouds, values = [x], [u]
    for axis in axes:
        for cloud, value in list(zip(clouds, values)):
            image, carried = cloud.copy(), value.copy()
            image[:, axis] *= -1
            carried[:, axis] *= -1
            clouds.append(image)
            values.append(carried)
    length = 1.3
    whole = smooth_increments(np.concatenate(clouds), np.concatenate(values), length,
                              fit=fit)
    got = smooth_increments(x, u, length, planes=[(a, 0.0) for a in axes], fit=fit)
    np.testing.assert_allclose(got, whole[:x.shape[0]], rtol=0, atol=1e-12)


def test_a_window_clock_keeps_a_steady_trend_steady():
    """A residual path that settles at a steady rate after a window opens late in the
    loading (cycles 110-120 of 50 Hz cycles): Shenton's law on the window's own clock
    (t = pT from the window's start, the procedure's fit_time = "window") extrapolates
    the steady rate exactly (a = 0, b = the rate), while the law on the loading clock
    without an intercept, tied to its zero at t = 0, bends the 80 extrapolated cycles
    away from it, here backwards."""
    rate = 0.0025e-3 / PERIOD                                  # [m/s], 0.0025 mm a cycle
    cycles = np.arange(110, 121)
    u = (rate * PERIOD * (cycles - 110))[:, None, None] * np.ones((1, 1, 3))
    true = rate * PERIOD * 90
    window = fit_residual(u, PERIOD * np.arange(11), "shenton")
    assert window.extrapolate(PERIOD * 90)[0, 0] == pytest.approx(true, rel=1e-9)
    loading = fit_residual(u, PERIOD * cycles, "shenton")
    assert loading.extrapolate(PERIOD * 200)[0, 0] < u[-1, 0, 0]


def test_forecast_of_a_path_from_its_own_past_by_hand():
    """A steady path is forecast exactly; a burst of settlement is missed by the
    forecasts made before it and overshot by those whose window holds it."""
    cycles = np.arange(101)
    steady = 1e-3 * (1 + 0.01 * cycles)
    assert np.allclose(forecast_errors(steady, 10, 20), 0.0, atol=1e-15)
    burst = steady + 1e-4 * (cycles >= 50)
    errors = forecast_errors(burst, 10, 20, first=5)
    assert errors.size == 101 - 20 - 15
    c = np.arange(15, 81)
    assert errors[c == 35][0] == pytest.approx(-1e-4 / burst[55], rel=1e-12)   # misses it
    assert errors[c == 55][0] == pytest.approx(2e-4 / burst[75], rel=1e-12)    # 20/10 of it
    assert np.allclose(errors[(c >= 60)], 0.0, atol=1e-15)
    with pytest.raises(ValueError, match="no window"):
        forecast_errors(steady[:20], 10, 20)
    with pytest.raises(ValueError, match=">= 1"):
        forecast_errors(steady, 0, 20)
