"""The convergence study of the settlement procedure (studies/settlement.py): on the
quick bed (120 soft grains, 8 cycles, k_i = 2, k and h in 2, 3) it settles one bed,
runs full DEM and the procedure from it, writes its tables and figures, and reuses the
bed and the finished runs when called again."""
import csv
import json
import math
import shutil

import numpy as np
import pytest
from typer.testing import CliRunner

from graindyn.cli import app
from graindyn.config.load import read_toml
from graindyn.studies.settlement import (FULL, QUICK, contact_coordination, plan,
                                         run_settlement_study, set_dotted, study_config)


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    out = tmp_path_factory.mktemp("settlement_study")
    lines = []
    summary = run_settlement_study(out, quick=True, ks=(2, 3), hs=(3,), echo=lines.append)
    return out, summary, lines


def test_the_study_writes_its_tables_and_figures(study):
    out, summary, _ = study
    for name in ("summary.csv", "paths.csv", "summary.json", "settlement_paths.png",
                 "settlement_errors.png"):
        assert (out / name).stat().st_size > 0, name
    assert json.loads((out / "summary.json").read_text())["runs"].keys() == \
        summary["runs"].keys()
    with open(out / "summary.csv") as f:
        rows = list(csv.DictReader(f))
    assert [r["run"] for r in rows] == list(summary["runs"])
    assert summary["families"] == {"k": ["shenton_ki2_k2_h2", "shenton_ki2_k3_h2"],
                                   "h": ["shenton_ki2_k3_h3"]}


def test_full_dem_against_itself_is_exact_and_the_errors_are_finite(study):
    _, summary, _ = study
    runs = summary["runs"]
    full = runs[FULL]
    for key in ("settlement_error", "coordination_error", "configuration_error",
                "path_error", "gained_time_percent"):
        assert full[key] == 0.0, key
    assert full["speedup"] == 1.0 and full["cycles_computed"] == 8
    for name, r in runs.items():
        assert r["cycles"] == 8, name
        for key in ("settlement_error", "coordination_error", "configuration_error",
                    "path_error", "gained_time_percent", "speedup", "cpu_s"):
            assert math.isfinite(r[key]), (name, key)
        assert r["settlement_m"] > 0 and r["coordination"] > 0
        # the definition of the gained time
        assert r["gained_time_percent"] == pytest.approx(
            100 * (full["cpu_s"] - r["cpu_s"]) / r["cpu_s"])
    # k_i = 2, k = 3, h = 3, N = 8: cycles 1-5 computed, 6-8 extrapolated
    r = runs["shenton_ki2_k3_h3"]
    assert (r["cycles_computed"], r["cycles_extrapolated"]) == (5, 3)
    assert summary["paths"]["shenton_ki2_k3_h3"][-1][2] == "extrapolated"
    assert r["largest_overlap_after"] < 1e-2


def test_every_run_starts_from_the_same_settled_bed(study):
    """Cycle 1 is computed by every run from the same checkpoint: the same settlement
    to the last bit."""
    _, summary, _ = study
    first = {name: path[0] for name, path in summary["paths"].items()}
    assert len({tuple(p) for p in first.values()}) == 1
    assert summary["bed"]["settle_time_s"] > 0


def test_a_second_call_reuses_the_bed_and_the_runs(study):
    out, summary, _ = study
    result = CliRunner().invoke(app, ["study", "settlement", "--quick", "--out", str(out),
                                      "--k", "2,3", "--h", "3"])
    assert result.exit_code == 0, result.output
    assert "bed: reusing" in result.output
    assert result.output.count("reusing the finished run") == len(summary["runs"])
    again = json.loads((out / "summary.json").read_text())
    assert again["runs"][FULL]["cpu_s"] == summary["runs"][FULL]["cpu_s"]


def test_a_bed_of_another_config_is_refused(study):
    out, _, _ = study
    result = CliRunner().invoke(app, ["study", "settlement", "--quick", "--out", str(out),
                                      "--set", "protocol.stress_amplitude=3e3"])
    assert result.exit_code == 2
    assert "bed of another config" in result.output


def test_configs_plans_and_overrides():
    data = study_config(QUICK, 480, {"protocol.plate_fraction": 0.8,
                                     "materials.sand.friction_sliding": 0.3})
    assert data["grains"]["count"] == 480
    assert data["walls"]["container"]["radius"] == pytest.approx(2 * 2.7e-3)
    assert data["protocol"]["plate_fraction"] == 0.8
    assert data["materials"][0]["friction_sliding"] == 0.3
    assert QUICK["grains"]["count"] == 120                      # the base is not changed
    with pytest.raises(ValueError, match="not a section"):
        set_dotted({"run": {"seed": 1}}, "run.seed.x", 2)
    runs, families = plan(100)
    assert len(runs) == 6          # full DEM and five procedures: (40, 10) is in both
    assert families["k"][2] == families["h"][0] == "shenton_ki10_k40_h10"
    assert runs["shenton_ki10_k20_h10"] == {
        "cycles": 100, "extrapolation": "shenton", "initial_cycles": 10,
        "computed_cycles": 20, "extrapolated_cycles": 10}


def test_contact_coordination_counts_overlapping_pairs():
    positions = np.array([[0.0, 0, 0], [1.9, 0, 0], [3.9, 0, 0], [10, 0, 0]])
    assert contact_coordination(positions, np.ones(4)) == pytest.approx(2 * 1 / 4)


def test_procedure_settings_go_to_the_runs_and_leave_the_bed(study, tmp_path):
    """--set of the procedure's own settings (smoothing, keep_contacts, the relaxation)
    reaches every run of the procedure, not full DEM, and the bed is reused."""
    out, _, _ = study
    shutil.copytree(out / "bed", tmp_path / "bed")
    lines = []
    summary = run_settlement_study(tmp_path, quick=True, ks=(3,), hs=(3,), k_fixed=3,
                                   h_fixed=3, overrides={"protocol.smoothing": 2.0,
                                                         "protocol.keep_contacts": True},
                                   echo=lines.append)
    assert any("bed: reusing" in line for line in lines)
    assert list(summary["runs"]) == [FULL, "shenton_ki2_k3_h3"]
    procedure = read_toml(tmp_path / "runs" / "shenton_ki2_k3_h3" / "config.toml")
    full = read_toml(tmp_path / "runs" / FULL / "config.toml")
    assert procedure["protocol"]["smoothing"] == 2.0
    assert procedure["protocol"]["keep_contacts"] is True
    assert full["protocol"]["smoothing"] == 0.0 and full["protocol"]["keep_contacts"] is False
