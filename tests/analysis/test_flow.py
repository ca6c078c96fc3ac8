"""The Beverloo fit of discharge rates (analysis/flow.py) on synthetic rates of known
parameters, and the silo sweep summary of holes too large to jam."""
import json
import math
from types import SimpleNamespace

import numpy as np
import pytest

from graindyn.analysis import avalanches
from graindyn.analysis.flow import beverloo, fit_beverloo

R = np.arange(5.0, 16.0)
A, K = 12.0, 1.6                # disks/s, -


def test_the_fit_recovers_known_parameters_within_their_errors():
    rng = np.random.default_rng(5)
    rate = beverloo(R, A, K)
    err = 0.03 * rate
    fit = fit_beverloo(R, rate + err * rng.standard_normal(R.size), err, d=0.005, g=9.81)
    assert abs(fit["A"] - A) < 3 * fit["A_err"] and abs(fit["k"] - K) < 3 * fit["k_err"]
    assert fit["A_err"] < 0.1 * A and fit["k_err"] < 0.5
    assert 0.2 < fit["chi2_per_dof"] < 3.0 and fit["dof"] == R.size - 2
    assert fit["C"] == pytest.approx(fit["A"] * math.sqrt(0.005 / 9.81))


def test_without_errors_the_fit_is_unweighted_and_exact_on_exact_data():
    fit = fit_beverloo(R, beverloo(R, A, K))
    assert fit["A"] == pytest.approx(A, rel=1e-6) and fit["k"] == pytest.approx(K, rel=1e-6)
    assert "chi2_per_dof" not in fit and "C" not in fit


@pytest.mark.parametrize("R_, rate, message", [
    ([5.0, 6.0], [10.0, 20.0], "cannot fit"),
    ([5.0, 6.0, 7.0], [30.0, 20.0, 10.0], "does not grow"),
    ([5.0, 6.0, 7.0], [np.nan, 0.0, 10.0], "cannot fit")])
def test_what_cannot_be_fitted_says_why(R_, rate, message):
    assert message in fit_beverloo(R_, rate)["error"]


def test_the_sweep_summary_fits_the_flow_rates_of_holes_too_large_to_jam(tmp_path):
    """Two seeds per hole, no finished avalanche (the silo flowed the whole run): the
    table lists the mean rate with its seed-to-seed error and the fit recovers k."""
    rng = np.random.default_rng(2)
    points = []
    for r in R:
        for seed in (1, 2):
            rate = beverloo(r, A, K) * (1 + 0.02 * rng.standard_normal())
            # each run measures R with its own mean diameter: 1e-3 R apart
            measured = r * (1 + (seed - 1.5) * 1e-3)
            points.append(SimpleNamespace(
                status="finished", name=f"hole={r}/seed-{seed}",
                results={"R": float(measured), "avalanches": [],
                         "mean_flow_rate_per_s": float(rate), "d_ave_m": 0.005,
                         "g_m_per_s2": 9.81}))
    avalanches.summarize_sweep(tmp_path, points)
    data = json.loads((tmp_path / "silo_sweep.json").read_text())
    fit = data["fits"]["beverloo"]
    assert abs(fit["k"] - K) < 3 * fit["k_err"] and abs(fit["A"] - A) < 3 * fit["A_err"]
    text = (tmp_path / "silo_sweep.md").read_text()
    assert "Beverloo in 2D" in text and "| 5.000 | 2 | 0 |" in text
    assert (tmp_path / "figures" / "silo_sweep.png").exists()
