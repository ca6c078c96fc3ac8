"""The sweep summaries on fake run results: summary.csv and summary.json (mean and spread
over seeds), the protocol hook, and the oedometer tables and h_s-eta figure with the
power-law fit recovering a known law."""
import csv
import json
import math

import numpy as np
import pytest

from graindyn import sweep as sweeps
from graindyn.protocols.deposition import Deposition
from graindyn.analysis import bauer_sweep
from graindyn.sweep import Sweep, finish

from .conftest import write_sweep

A, B = 2.0, -4.0                 # the law h_s [MPa] = A eta^B behind the fake results
ETA = {"reference": 0.60, "friction_sliding=0.2": 0.50, "friction_sliding=0.4": 0.55,
       "youngs_modulus=1e7": 0.68, "youngs_modulus=1e9": 0.75}


def _bauer(eta, h_s_MPa, factor=1.0):
    return {"pressure": "x", "e0": 0.7, "e0_err": 0.01, "e0_fixed": False,
            "h_s_Pa": factor * h_s_MPa * 1e6, "h_s_err_Pa": 0.03 * factor * h_s_MPa * 1e6,
            "eta": eta, "eta_err": 0.01, "eta_err_extra": None, "rms": 1e-3, "points": 8}


@pytest.fixture
def fake(tmp_path):
    """A sweep of 15 runs with fake results: seeds 1, 2, 3; one failed run
    (friction_sliding=0.4/seed-3), one that never ran (youngs_modulus=1e9/seed-2)."""
    path = write_sweep(tmp_path, {"seeds": [1, 2, 3], "vary": [
        {"parameter": "materials.sand.friction_sliding", "values": [0.2, 0.4]},
        {"parameter": "materials.sand.youngs_modulus", "values": [1e7, 1e9],
         "label": "V [GPa]", "display": [0.01, 1.0]}]})
    sweep = Sweep.load(path)
    out = tmp_path / "out"
    sweeps.prepare(sweep, out)
    rng = np.random.default_rng(7)
    truth = {}
    for k, p in enumerate(sweep.runs):
        folder = out / p.name
        folder.mkdir(parents=True)
        if p.name == "friction_sliding=0.4/seed-3":
            (folder / "error.txt").write_text("SimulationError: it broke\n\nTraceback ...")
            continue
        if p.name == "youngs_modulus=1e9/seed-2":
            continue
        eta = ETA[p.name.split("/")[0]] * (1 + 0.01 * rng.standard_normal())
        h_s = A * eta**B * np.exp(0.02 * rng.standard_normal())
        results = {"steps": 1000 + k, "packing_fraction": 0.6 + 0.001 * k,
                   "reached": True, "criterion": "EnergyRatioBelow", "levels": [1, 2],
                   "nan_result": math.nan, "energy_J": {"kinetic": 1e-9 * (k + 1)},
                   "bauer": {"vertical": _bauer(eta, h_s), "trace": _bauer(eta, h_s, 3.0)}}
        (folder / "results.json").write_text(json.dumps(results))
        truth[p.name] = results
    return sweep, out, truth


def _rows(out):
    with open(out / "summary.csv", newline="") as f:
        return list(csv.DictReader(f))


def test_summary_csv_has_a_row_per_point(fake):
    sweep, out, truth = fake
    report = finish(sweep, out, say=lambda *a, **k: None)
    rows = _rows(out)
    assert len(rows) == len(sweep.points) == 15
    assert {"parameter", "value", "seed", "status", "directory", "bauer.vertical.h_s_Pa",
            "bauer.trace.eta", "energy_J.kinetic", "steps", "reached"} <= set(rows[0])
    assert "criterion" not in rows[0] and "levels" not in rows[0]
    by_dir = {r["directory"]: r for r in rows}
    row = by_dir["friction_sliding=0.2/seed-2"]
    assert (row["parameter"], row["value"], row["seed"], row["status"]) == (
        "materials.sand.friction_sliding", "0.2", "2", "finished")
    assert float(row["bauer.vertical.h_s_Pa"]) == \
        truth["friction_sliding=0.2/seed-2"]["bauer"]["vertical"]["h_s_Pa"]
    failed = by_dir["friction_sliding=0.4/seed-3"]
    assert failed["status"] == "failed" and failed["error"] == "SimulationError: it broke"
    assert failed["bauer.vertical.h_s_Pa"] == ""
    assert by_dir["youngs_modulus=1e9/seed-2"]["status"] == "pending"
    assert by_dir["reference/seed-1"]["parameter"] == "reference"
    assert report.exit_code == 1
    assert [p.name for p in report.failed] == ["friction_sliding=0.4/seed-3"]
    assert [p.name for p in report.pending] == ["youngs_modulus=1e9/seed-2"]


def test_summary_json_mean_and_spread_over_seeds(fake):
    sweep, out, truth = fake
    finish(sweep, out, say=lambda *a, **k: None)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["runs"] == {"finished": 13, "failed": 1, "pending": 1}
    groups = {(g["parameter"], json.dumps(g["value"])): g for g in summary["groups"]}
    assert len(groups) == 5
    g = groups[("materials.sand.friction_sliding", "0.2")]
    values = [truth[f"friction_sliding=0.2/seed-{s}"]["bauer"]["vertical"]["h_s_Pa"]
              for s in (1, 2, 3)]
    assert g["finished"] == 3 and g["seeds"] == [1, 2, 3]
    assert g["mean"]["bauer.vertical.h_s_Pa"] == pytest.approx(np.mean(values), rel=1e-12)
    assert g["std"]["bauer.vertical.h_s_Pa"] == pytest.approx(np.std(values, ddof=1),
                                                              rel=1e-12)
    assert g["count"]["steps"] == 3
    assert "reached" not in g["mean"] and "nan_result" not in g["mean"]
    # the failed seed is left out of the statistics, and listed
    g = groups[("materials.sand.friction_sliding", "0.4")]
    steps = [truth[f"friction_sliding=0.4/seed-{s}"]["steps"] for s in (1, 2)]
    assert g["failed"] == ["friction_sliding=0.4/seed-3"]
    assert g["mean"]["steps"] == np.mean(steps) and g["count"]["steps"] == 2
    # one finished seed: no spread
    g = groups[("materials.sand.youngs_modulus", "1000000000.0")]
    assert g["finished"] == 2 and g["pending"] == ["youngs_modulus=1e9/seed-2"]
    assert g["display"] == 1.0 and g["label"] == "V [GPa]"
    ref = groups[(None, "null")]
    assert ref["finished"] == 3 and ref["std"]["packing_fraction"] > 0


def test_single_seed_has_no_spread():
    point = sweeps.Point(None, "reference", None, None, None, 1, "reference/seed-1", None,
                         status="finished", results={"x": 2.0, "y": {"z": 3}})
    mean, std, count = sweeps.statistics([point])
    assert mean == {"x": 2.0, "y.z": 3.0} and std == {"x": None, "y.z": None}


def test_protocol_hook_is_called_and_its_failure_reported(fake, monkeypatch):
    sweep, out, _ = fake
    calls = []

    def hook(sweep_dir, points):
        calls.append((sweep_dir, points))
        (sweep_dir / "extra.md").write_text("hi")
        return [sweep_dir / "extra.md"]

    monkeypatch.setattr(Deposition, "summarize_sweep", staticmethod(hook), raising=False)
    report = finish(sweep, out, say=lambda *a, **k: None)
    assert calls and calls[0][0] == out and len(calls[0][1]) == 15
    assert calls[0][1][0].results["steps"] > 0
    assert out / "extra.md" in report.paths

    def broken(sweep_dir, points):
        raise ValueError("cannot fit")

    monkeypatch.setattr(Deposition, "summarize_sweep", staticmethod(broken))
    lines = []
    report = finish(sweep, out, say=lambda text, style=None: lines.append(text))
    assert report.summary_error == "ValueError: cannot fit" and report.exit_code == 1
    assert "cannot fit" in (out / "summary_error.txt").read_text()
    assert any("deposition summary failed: ValueError: cannot fit" in x for x in lines)
    assert (out / "summary.csv").exists()


def test_plus_minus_formatting():
    assert bauer_sweep.pm(0.41234, 0.0123) == "0.412 ± 0.012"
    assert bauer_sweep.pm(35.23, 1.3) == "35.2 ± 1.3"
    assert bauer_sweep.pm(1234.4, 56.0) == "1234 ± 56"
    assert bauer_sweep.pm(math.nan, 1.0) == "–"


def test_combine_takes_the_larger_of_spread_and_fit_error():
    mean, err = bauer_sweep.combine([1.0, 2.0, 3.0], [0.1, 0.1, 0.1])
    assert mean == 2.0 and err == pytest.approx(1.0)          # spread wins
    mean, err = bauer_sweep.combine([1.0, 1.0], [3.0, 4.0])
    assert err == pytest.approx(2.5)                          # sqrt(9 + 16) / 2


def test_oedometer_summary_tables_figure_and_fit(fake, monkeypatch):
    sweep, out, truth = fake
    # the oedometer's summary, given to this protocol
    monkeypatch.setattr(Deposition, "summarize_sweep",
                        staticmethod(bauer_sweep.summarize_sweep))
    report = finish(sweep, out, say=lambda *a, **k: None)
    for name in ("bauer_vertical.md", "bauer_trace.md", "bauer_sweep.json",
                 "figures/hs_eta_vertical.png", "figures/hs_eta_trace.png",
                 "figures/compression.png"):
        assert (out / name).stat().st_size > 0, name
        assert out / name in report.paths
    table = (out / "bauer_vertical.md").read_text()
    assert "## V [GPa] (materials.sand.youngs_modulus)" in table
    assert "## friction_sliding (materials.sand.friction_sliding)" in table
    # the reference row sits in each table at its value, V shown in GPa like the others
    assert "| 0.1 (reference) |" in table and "| 0.5 (reference) |" in table
    friction = table.split("## friction_sliding")[1].split("##")[0]
    assert friction.index("| 0.2 |") < friction.index("| 0.4 |") < \
        friction.index("| 0.5 (reference) |")
    # one row by hand: the mean over seeds +- max(spread, propagated fit error)
    fits = [truth[f"friction_sliding=0.2/seed-{s}"]["bauer"]["vertical"] for s in (1, 2, 3)]
    h_s = np.array([f["h_s_Pa"] for f in fits]) / 1e6
    err = max(np.std(h_s, ddof=1), np.sqrt(np.sum((0.03 * h_s) ** 2)) / 3)
    eta = np.array([f["eta"] for f in fits])
    eta_err = max(np.std(eta, ddof=1), np.sqrt(3 * 0.01**2) / 3)
    row = f"| 0.2 | {bauer_sweep.pm(eta.mean(), eta_err)} | " \
          f"{bauer_sweep.pm(h_s.mean(), err)} | 3/3 |"
    assert row in table
    assert "| 2/3 |" in friction                               # the failed seed
    # the power law over the five distinct points recovers the law behind the data
    summary = json.loads((out / "bauer_sweep.json").read_text())
    for measure, factor in (("vertical", 1.0), ("trace", 3.0)):
        fit = summary["measures"][measure]["power_law"]
        assert fit["points"] == 5
        assert fit["b"] == pytest.approx(B, abs=0.15)
        assert fit["a"] == pytest.approx(factor * A, rel=0.1)
        assert 0 < fit["b_err"] < 0.15 and 0 < fit["a_err"] < 0.1 * factor * A
        assert f"a = {bauer_sweep.pm(fit['a'], fit['a_err'])} MPa" in \
            (out / f"bauer_{measure}.md").read_text()
    assert summary["guamo"]["h_s_MPa"] == 19.1 and summary["paper_fit"]["b"] == -9.88


def test_oedometer_summary_without_enough_points(tmp_path):
    sweep = Sweep.load(write_sweep(tmp_path, {"seeds": [1]}))
    out = tmp_path / "out"
    (out / "reference" / "seed-1").mkdir(parents=True)
    (out / "reference" / "seed-1" / "results.json").write_text(json.dumps(
        {"bauer": {"vertical": _bauer(0.6, 10.0), "trace": _bauer(0.6, 30.0)},
         "stopped_early": {"level": 8, "target_Pa": 3.2e6, "reason": "overlap"}}))
    paths = bauer_sweep.summarize_sweep(out, sweeps.collect(sweep, out))
    assert out / "figures" / "hs_eta_trace.png" in paths
    text = (out / "bauer_vertical.md").read_text()
    assert "too few points for a power-law fit" in text and "| 0.600 ± 0.010 |" in text
    assert "| 1/1, ladder stopped at 3.2 MPa |" in text


def test_seed_rows_keep_spread_and_fit_error_apart(fake):
    """The seed table gives the seed spread and the mean fit error side by side (the
    main tables show only the larger of the two)."""
    sweep, out, truth = fake
    rows = bauer_sweep.seed_rows(sweeps.collect(sweep, out), "vertical")
    row = next(r for r in rows if r["label"] == "friction_sliding" and r["display"] == 0.2)
    eta = [truth[f"friction_sliding=0.2/seed-{s}"]["bauer"]["vertical"]["eta"]
           for s in (1, 2, 3)]
    assert row["fitted"] == 3 and row["eta"] == pytest.approx(np.mean(eta))
    assert row["eta_spread"] == pytest.approx(np.std(eta, ddof=1))
    assert row["eta_fit_err"] == pytest.approx(0.01)
    assert "## Seed to seed" in bauer_sweep.seed_table(sweeps.collect(sweep, out),
                                                        "vertical")


def test_refit_without_the_first_level_recovers_the_law_behind_the_others():
    """A ladder on Bauer's law (e0 0.9, h_s 500 MPa, eta 0.6) whose first level sits off
    the curve: left out, the refit gives the law back."""
    from graindyn.analysis.bauer import bauer

    p = 12.5e3 * 2.0 ** np.arange(8)
    e = bauer(p, 0.9, 500e6, 0.6)
    e[0] += 0.004
    ladder = [{"level": k, "sigma_top_Pa": float(p[k]), "trace_Pa": float(2 * p[k]),
               "void_ratio": float(e[k]), "K0": 0.5 + 0.01 * k} for k in range(8)]
    results = {"ladder": ladder, "bauer": {"vertical": {"levels": list(range(8))}}}
    eta, h_s = bauer_sweep._refit_without_first(results, "vertical")
    assert eta == pytest.approx(0.6, rel=1e-6) and h_s == pytest.approx(500e6, rel=1e-6)
