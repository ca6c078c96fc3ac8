"""The integrator study in its quick form: every output is written, and what it
reports agrees with the exact solutions it is measured against."""
import csv
import json

import pytest

from graindyn.engines.soft.integrators import NAMES
from graindyn.studies.integrators import OQUENDO_SCHEMES, PEREZ_SPEED, run_integrator_study


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    out = tmp_path_factory.mktemp("integrators")
    return out, run_integrator_study(out, quick=True)


def test_outputs_written(study):
    out, summary = study
    for name in ("oquendo_fig2_energy_spread.png", "perez_fig3_collision_velocity_error.png",
                 "order_of_accuracy.png", "oquendo_energy_spread.csv",
                 "perez_collision_velocity_error.csv", "order_of_accuracy.csv",
                 "order_of_accuracy_summary.csv", "symmetric_top.csv"):
        assert (out / name).stat().st_size > 0, name
    assert json.loads((out / "summary.json").read_text()) == summary
    with open(out / "oquendo_energy_spread.csv") as f:
        assert next(csv.reader(f))[:2] == ["scheme", "dt_s"]


def test_oquendo_energy_spread(study):
    """Second order (spread ~ dt^2), and the optimized velocity Verlet keeps the
    energy best at every dt, as Oquendo found."""
    out, summary = study
    for name, slope in summary["oquendo_fig2"]["loglog_slope"].items():
        assert 1.8 < slope < 2.6, name
    with open(out / "oquendo_energy_spread.csv") as f:
        rows = list(csv.DictReader(f))
    for ratio in {r["collision_time_over_dt"] for r in rows}:
        spread = {r["scheme"]: float(r["energy_spread_J"]) for r in rows
                  if r["collision_time_over_dt"] == ratio}
        assert set(spread) == set(OQUENDO_SCHEMES)
        assert spread["optimized_velocity_verlet"] < spread["verlet"]


def test_perez_collision_errors_small_and_alike(study):
    """Perez Fig. 3: the three schemes are alike, the error being set by the contact
    discontinuity: each stays below 1e-3 of the impact speed."""
    _, summary = study
    errors = [v["max_abs_velocity_error_m_per_s"] for v in summary["perez_fig3"].values()]
    assert max(errors) < 1e-3 * PEREZ_SPEED
    assert max(errors) < 10 * min(errors)


def test_order_table_covers_every_scheme(study):
    _, summary = study
    orders = summary["order_of_accuracy"]
    assert set(orders) == set(NAMES)
    assert orders["velocity_verlet"]["damped"]["order"] == pytest.approx(2.0, abs=0.1)
    assert orders["gear6"]["undamped"]["order"] == pytest.approx(5.0, abs=0.2)


def test_symmetric_top_table(study):
    """The top's precession-rate error is second order in dt and below 1e-3 at
    dt |w| = 0.01 (VALIDATION G2)."""
    _, summary = study
    top = summary["symmetric_top"]
    assert abs(top["0.01"]["precession_rate_error"]) < 1e-3
    ratio = top["0.02"]["precession_rate_error"] / top["0.01"]["precession_rate_error"]
    assert ratio == pytest.approx(4.0, rel=0.05)
