"""The convergence study of the settlement procedure (studies/settlement.py): on the
quick bed (120 soft grains, 8 cycles, k_i = 2, k and h in 2, 3) it settles one bed,
runs full DEM and the procedure from it, writes its tables and figures, and reuses the
bed and the finished runs when called again."""
import csv
import json
import math
import os
import shutil
import signal
import threading
import time

import numpy as np
import pytest
from typer.testing import CliRunner

from graindyn.cli import app
from graindyn.config.load import read_toml
from graindyn.runner import RunInterrupted
from graindyn.analysis.settlement import forecast_errors
from graindyn.studies.settlement import (FULL, PARTIAL, QUICK, contact_coordination,
                                         ensemble, perturb, perturbation_of, plan,
                                         reference_of, run_from_bed,
                                         run_settlement_study, set_dotted,
                                         settlement_path, study_config, study_standing)


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    out = tmp_path_factory.mktemp("settlement_study")
    lines = []
    summary = run_settlement_study(out, quick=True, ks=(2, 3), hs=(3,), replicas=1,
                                   echo=lines.append)
    return out, summary, lines


def test_the_study_writes_its_tables_and_figures(study):
    out, summary, _ = study
    for name in ("summary.csv", "paths.csv", "summary.json", "settlement_paths.png",
                 "settlement_errors.png", "settlement_relaxation.png"):
        assert (out / name).stat().st_size > 0, name
    assert json.loads((out / "summary.json").read_text())["runs"].keys() == \
        summary["runs"].keys()
    with open(out / "summary.csv") as f:
        rows = list(csv.DictReader(f))
    assert [r["run"] for r in rows] == list(summary["runs"])
    assert summary["families"] == {"k": ["shenton_ki2_k2_h2", "shenton_ki2_k3_h2"],
                                   "h": ["shenton_ki2_k3_h3"],
                                   "replica": ["full_dem_replica_1"],
                                   "procedure_replica": []}


def test_full_dem_against_itself_is_exact_and_the_errors_are_finite(study):
    _, summary, _ = study
    runs = summary["runs"]
    full = runs[FULL]
    for key in ("settlement_error", "coordination_error", "configuration_error",
                "path_error", "gained_time_percent"):
        assert full[key] == 0.0, key
    assert full["speedup"] == 1.0 and full["cycles_computed"] == 8
    assert all(r["undone_jumps"] == r["cycles_computed_again"] == 0 for r in runs.values())
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
    to the last bit; the replica, one grain moved by 1 nm, lands elsewhere."""
    _, summary, _ = study
    first = {name: path[0] for name, path in summary["paths"].items()
             if name not in summary["families"]["replica"]}
    assert len({tuple(p) for p in first.values()}) == 1
    assert summary["paths"]["full_dem_replica_1"][0] != first[FULL]
    assert summary["bed"]["settle_time_s"] > 0


def test_a_replica_is_full_dem_of_the_bed_with_one_grain_moved(study):
    """Replica 1 starts from the settled bed with one grain moved by 1 nm and runs the
    cycles of full DEM: not the same computation (its residual displacements differ),
    and its errors are the summary's noise."""
    out, summary, lines = study
    r = summary["runs"]["full_dem_replica_1"]
    assert (r["cycles_computed"], r["cycles_extrapolated"]) == (8, 0)
    assert r["configuration_error"] > 0 and r["settlement_m"] > 0
    assert any("full_dem_replica_1: grain" in line and "moved by 1e-09 m" in line
               for line in lines)
    noise = summary["noise"]
    for key in ("settlement_error", "coordination_error", "configuration_error",
                "path_error"):
        assert tuple(noise[key]) == (r[key], r[key]), key
    # full DEM forecast from its own past, from cycle k_i = 2 on, for k = 2, 3 and
    # h = 2, 3 (the study's 8 cycles are too few for FORECAST_HORIZONS)
    settlement = [s for _, s, _ in summary["paths"][FULL]]
    assert set(summary["forecast"]) == {"k2_h2", "k2_h3", "k3_h2", "k3_h3"}
    errors = forecast_errors(settlement, 3, 2, first=1)
    assert summary["forecast"]["k3_h2"] == {"rms": pytest.approx(np.sqrt(np.mean(errors**2))),
                                            "mean": pytest.approx(np.mean(errors)),
                                            "forecasts": 8 - 2 - 4}


def test_perturb_moves_the_free_grain_nearest_the_centre(tmp_path):
    import h5py

    positions = np.array([[0.0, 0, 0], [1.0, 0, 0], [2.0, 0, 0], [3.0, 0, 0], [4.0, 0, 0]])
    fixed = np.array([0, 0, 1, 0, 0], np.int8)          # the centre grain (2) is held
    with h5py.File(tmp_path / "c.h5", "w") as f:
        f["grains/positions"] = positions
        f["grains/fixed"] = fixed
    grain = perturb(tmp_path / "c.h5", 1e-9)
    with h5py.File(tmp_path / "c.h5") as f:
        moved = f["grains/positions"][...]
    assert grain == 1                                   # nearest the free grains' centre
    assert moved[1, 0] == 1.0 + 1e-9
    assert np.array_equal(np.delete(moved, 1, axis=0), np.delete(positions, 1, axis=0))


def test_a_second_call_reuses_the_bed_and_the_runs(study):
    out, summary, _ = study
    result = CliRunner().invoke(app, ["study", "settlement", "--quick", "--out", str(out),
                                      "--k", "2,3", "--h", "3", "--replicas", "1"])
    assert result.exit_code == 0, result.output
    assert "full DEM forecast from its own past (rms relative error): k2 h2 " in result.output
    assert ", k3 h3 " in result.output
    assert "bed: reusing" in result.output
    assert result.output.count("reusing the finished run") == len(summary["runs"])
    again = json.loads((out / "summary.json").read_text())
    assert again["runs"][FULL]["cpu_s"] == summary["runs"][FULL]["cpu_s"]


def test_a_finished_run_is_not_deleted_for_other_settings(study):
    """The same study with another procedure setting (smoothing) is refused before
    anything runs, naming the setting, and the finished runs stay as they were."""
    out, summary, _ = study
    before = {f: f.stat().st_mtime_ns for f in out.rglob("*")}
    with pytest.raises(ValueError, match=r"finished run made with other settings "
                                         r"\(smoothing None -> 1.0\)"):
        run_settlement_study(out, quick=True, ks=(2, 3), hs=(3,), replicas=1,
                             overrides={"protocol.smoothing": 1.0}, echo=lambda *a: None)
    assert {f: f.stat().st_mtime_ns for f in out.rglob("*")} == before


def test_status_of_a_finished_study_writes_nothing(study):
    out, summary, _ = study
    before = {f: f.stat().st_mtime_ns for f in out.rglob("*")}
    result = CliRunner().invoke(app, ["study", "settlement", "--quick", "--out", str(out),
                                      "--k", "2,3", "--h", "3", "--replicas", "1",
                                      "--status"])
    assert result.exit_code == 0, result.output
    runs = len(summary["runs"]) + 1              # and the bed
    assert f"{out}: {runs} runs, {runs} finished" in result.output
    assert {f: f.stat().st_mtime_ns for f in out.rglob("*")} == before


def test_status_reads_the_bed_and_each_run_from_their_files(tmp_path):
    """The bed settled, full DEM finished here, a procedure run finished only in the
    keep folder, one started (the simulated time and the last line of its log) and
    one not started, in the plan's order."""
    out, keep = tmp_path / "out", tmp_path / "keep"
    (out / "bed").mkdir(parents=True)
    (out / "bed" / "bed.json").write_text("{}")
    for folder in (out / "runs" / FULL, keep / "runs" / "linear_ki2_k2_h2"):
        folder.mkdir(parents=True)
        (folder / "study_run.json").write_text("{}")
    started = out / "runs" / "linear_ki2_k3_h2"
    started.mkdir(parents=True)
    (started / "run.log").write_text(
        "2026-12-06 02:00:00,000 resume from t = 0.5 s (step 1), 1 threads\n"
        "2026-12-06 02:00:10,000 cycle 3 ended at t = 0.52 s: settlement 1e-05 m\n")
    rows = study_standing(out, keep=keep, now=(started / "run.log").stat().st_mtime + 5.0,
                          quick=True, estimator="linear")
    assert [(r["name"], r["state"]) for r in rows] == [
        ("bed", "finished"), (FULL, "finished"), ("linear_ki2_k2_h2", "finished"),
        ("linear_ki2_k3_h2", "started"), ("linear_ki2_k3_h3", "not started")]
    assert rows[2]["kept"] and "kept" not in rows[1]
    assert rows[3]["simulated_s"] == 0.52 and rows[3]["rate"] is None
    assert rows[3]["news"] == "cycle 3 ended at t = 0.52 s: settlement 1e-05 m"
    assert rows[3]["quiet_s"] == pytest.approx(5.0)


def _terminate_when(log, text, timeout=600.0):
    """Send this process SIGTERM once the file ``log`` holds ``text``."""
    deadline = time.time() + timeout
    while time.time() < deadline and not (log.exists() and text in log.read_text()):
        time.sleep(0.01)
    os.kill(os.getpid(), signal.SIGTERM)


def test_an_interrupted_run_resumes_from_its_checkpoint_and_sums_its_times(study, tmp_path):
    """SIGTERM while a study run is on its cycles: RunInterrupted, the session's times
    kept in study_partial.json; the next call resumes the run from its checkpoint, to
    the same settlement path as the study's uninterrupted full DEM run, with both
    sessions' CPU times; a session that ended without closing its file starts over."""
    out, summary, _ = study
    bed = tmp_path / "bed"
    shutil.copytree(out / "bed", bed)
    settings, _ = plan(8, 2, (2,), (2,), 3, 2)
    folder = tmp_path / "run"
    stop = threading.Thread(target=_terminate_when, args=(folder / "run.log", "cycle 2:"))
    stop.start()
    with pytest.raises(RunInterrupted):
        run_from_bed(bed, settings[FULL], folder, echo=lambda *a: None)
    stop.join()
    partial = json.loads((folder / PARTIAL).read_text())
    assert partial["closed"] and partial["sessions"] == 1
    assert partial["cpu_s"] > 0 and partial["steps"] > 0
    lines = []
    record = run_from_bed(bed, settings[FULL], folder, echo=lines.append)
    assert any("resuming from its checkpoint" in line for line in lines)
    assert record["path"] == summary["paths"][FULL]
    assert record["sessions"] == 2 and record["cpu_s"] > partial["cpu_s"]
    whole = json.loads((out / "runs" / FULL / "study_run.json").read_text())
    assert record["steps"] == whole["steps"]
    assert not (folder / PARTIAL).exists()
    (folder / "study_run.json").unlink()
    (folder / PARTIAL).write_text(json.dumps({**partial, "closed": False}))
    lines = []
    again = run_from_bed(bed, settings[FULL], folder, echo=lines.append)
    assert not any("resuming" in line for line in lines)
    assert again["sessions"] == 1 and again["path"] == summary["paths"][FULL]


def test_a_signal_to_a_study_of_two_jobs_stops_both_workers(study, tmp_path):
    """SIGTERM to the study alone while two runs go on in its two worker processes:
    both workers get it, write their checkpoints and stop (study_partial.json closed),
    no other run starts, and the study raises RunInterrupted."""
    out, _, _ = study
    new = tmp_path / "study"
    new.mkdir()
    shutil.copytree(out / "bed", new / "bed")
    logs = [new / "runs" / name / "run.log" for name in (FULL, "shenton_ki2_k2_h2")]

    def terminate():
        deadline = time.time() + 600.0
        while time.time() < deadline and not all(
                log.exists() and "cycle 1:" in log.read_text() for log in logs):
            time.sleep(0.01)
        os.kill(os.getpid(), signal.SIGTERM)

    stop = threading.Thread(target=terminate)
    stop.start()
    with pytest.raises(RunInterrupted):
        run_settlement_study(new, quick=True, ks=(2, 3), hs=(3,), jobs=2,
                             echo=lambda *a: None)
    stop.join()
    assert sorted(d.name for d in (new / "runs").iterdir()) == sorted(
        log.parent.name for log in logs)
    for log in logs:
        partial = json.loads((log.parent / PARTIAL).read_text())
        assert partial["closed"] and partial["sessions"] == 1, log.parent.name


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
    runs, families = plan(100, replicas=2)
    assert families["replica"] == ["full_dem_replica_1", "full_dem_replica_2"]
    assert runs["full_dem_replica_2"] == {"cycles": 100, "extrapolation": "none"}
    with pytest.raises(ValueError, match="replicas"):
        plan(100, replicas=-1)
    assert families["k"][2] == families["h"][0] == "shenton_ki10_k40_h10"
    assert runs["shenton_ki10_k20_h10"] == {
        "cycles": 100, "extrapolation": "shenton", "initial_cycles": 10,
        "computed_cycles": 20, "extrapolated_cycles": 10}


def test_contact_coordination_counts_overlapping_pairs():
    positions = np.array([[0.0, 0, 0], [1.9, 0, 0], [3.9, 0, 0], [10, 0, 0]])
    assert contact_coordination(positions, np.ones(4)) == pytest.approx(2 * 1 / 4)


def test_procedure_settings_go_to_the_runs_and_leave_the_bed(study, tmp_path):
    """--set of the procedure's own settings (smoothing, keep_contacts, the relaxation)
    reaches every run of the procedure, not full DEM, and the bed and full DEM are
    reused."""
    out, _, _ = study
    shutil.copytree(out / "bed", tmp_path / "bed")
    shutil.copytree(out / "runs" / FULL, tmp_path / "runs" / FULL)
    lines = []
    summary = run_settlement_study(tmp_path, quick=True, ks=(3,), hs=(3,), k_fixed=3,
                                   h_fixed=3, overrides={"protocol.smoothing": 2.0,
                                                         "protocol.keep_contacts": True},
                                   echo=lines.append)
    assert any("bed: reusing" in line for line in lines)
    assert f"{FULL}: reusing the finished run" in lines
    assert list(summary["runs"]) == [FULL, "shenton_ki2_k3_h3"]
    procedure = read_toml(tmp_path / "runs" / "shenton_ki2_k3_h3" / "config.toml")
    full = read_toml(tmp_path / "runs" / FULL / "config.toml")
    assert procedure["protocol"]["smoothing"] == 2.0
    assert procedure["protocol"]["keep_contacts"] is True
    assert full["protocol"]["smoothing"] == 0.0 and full["protocol"]["keep_contacts"] is False


def test_a_run_with_checked_jumps_counts_the_undone_ones(study, tmp_path):
    """A procedure whose jumps all fail their check (jump_tolerance = 1e-12; k_i = 2,
    k = 3, h = 3 over 12 cycles, final_cycles = 3): the jumps 5 -> 8 and 8 -> 9 undone,
    the 3 + 3 cycles computed after them counted as computed again, and every one of
    the 12 cycles computed in the end."""
    out, _, _ = study
    settings = {"cycles": 12, "extrapolation": "linear", "initial_cycles": 2,
                "computed_cycles": 3, "extrapolated_cycles": 3, "final_cycles": 3,
                "jump_tolerance": 1e-12}
    record = run_from_bed(out / "bed", settings, tmp_path / "checked", echo=lambda *a: None)
    assert (record["undone_jumps"], record["undone_cycles"]) == (2, 6)
    assert (record["computed_cycles"], record["extrapolated_cycles"]) == (12, 0)


def test_procedure_replicas_are_planned_against_full_dem_of_their_own_bed():
    runs, families = plan(100, ks=(10,), hs=(20,), k_fixed=10, h_fixed=20, replicas=2,
                          procedure_replicas=2)
    name = "shenton_ki10_k10_h20"
    assert families["procedure_replica"] == [f"{name}_replica_1", f"{name}_replica_2"]
    assert runs[f"{name}_replica_2"] == runs[name]
    assert perturbation_of(f"{name}_replica_2") == perturbation_of("full_dem_replica_2") \
        == 2e-9
    assert perturbation_of(name) == 0.0
    assert reference_of(f"{name}_replica_2") == "full_dem_replica_2"
    assert reference_of("full_dem_replica_2") == reference_of(name) == FULL
    with pytest.raises(ValueError, match="between 0 and the replicas of full DEM"):
        plan(100, replicas=1, procedure_replicas=2)


def _record(path, cpu):
    return {"path": [[c, s, "computed"] for c, s in path], "cycle": path[-1][0],
            "settlement_m": path[-1][1], "cpu_s": cpu}


def test_an_ensemble_averages_the_pairs_differences():
    """Three beds: full DEM settles 1, 2, 3 mm per cycle; the procedure, reporting only
    cycles 1 and 4 (a jump in between), lands 0.3, -0.1 and 0.4 mm off at cycle 4."""
    cycles = (1, 2, 3, 4)
    records = {}
    off = (0.3e-3, -0.1e-3, 0.4e-3)
    for r, rate in enumerate((1e-3, 2e-3, 3e-3)):
        records[f"f{r}"] = _record([(c, rate * c) for c in cycles], 100.0)
        records[f"p{r}"] = _record([(1, rate), (4, 4 * rate + off[r])], 25.0 + r)
    e = ensemble(records, [(f"p{r}", f"f{r}") for r in range(3)])
    mean_full = 4 * 2e-3
    d = np.array(off)
    assert e["cycle"] == 4
    assert e["settlement_bias"] == pytest.approx(d.mean() / mean_full)
    assert e["settlement_bias_se"] == pytest.approx(d.std(ddof=1) / math.sqrt(3) / mean_full)
    assert e["mean_settlement_error"] == pytest.approx(
        np.mean(np.abs(d) / (4e-3 * np.arange(1, 4))))
    assert e["full_spread"] == pytest.approx(np.std([4e-3, 8e-3, 12e-3], ddof=1) / mean_full)
    # the jump is linear between cycles 1 and 4: a third of the offset at cycle 2
    assert e["path_bias"][1] == pytest.approx(d.mean() / 3 / (2 * 2e-3))
    assert e["path_bias_largest"] == pytest.approx(abs(e["settlement_bias"]))
    assert e["path_bias_cycle"] == 4
    assert e["speedup"] == pytest.approx(300.0 / 78.0)
    with pytest.raises(ValueError, match="at least two"):
        ensemble(records, [("p0", "f0")])


def test_a_procedure_replica_runs_from_the_bed_of_its_full_dem_replica(study, tmp_path):
    """--procedure-replicas 1 on the study's folder: the procedure run repeated from the
    bed of full DEM replica 1 (its first cycle that replica's to the bit, another than
    the unperturbed run's), compared with that replica; the ensemble of the two pairs
    and its figure written; every other run reused."""
    out, _, _ = study
    shutil.copytree(out / "bed", tmp_path / "bed")
    for name in (FULL, "full_dem_replica_1", "shenton_ki2_k3_h3"):
        shutil.copytree(out / "runs" / name, tmp_path / "runs" / name)
    lines = []
    summary = run_settlement_study(tmp_path, quick=True, ks=(3,), hs=(3,), k_fixed=3,
                                   h_fixed=3, replicas=1, procedure_replicas=1,
                                   echo=lines.append)
    replica = "shenton_ki2_k3_h3_replica_1"
    assert sum("reusing the finished run" in line for line in lines) == 3
    assert summary["families"]["procedure_replica"] == [replica]
    paths = summary["paths"]
    assert paths[replica][0] == paths["full_dem_replica_1"][0] != paths[FULL][0]
    row = summary["runs"][replica]
    assert row["reference"] == "full_dem_replica_1"
    assert row["settlement_error"] == pytest.approx(
        abs(row["settlement_m"] - summary["runs"]["full_dem_replica_1"]["settlement_m"])
        / summary["runs"]["full_dem_replica_1"]["settlement_m"])
    e = summary["ensembles"]["shenton_ki2_k3_h3"]
    assert e["pairs"] == [["shenton_ki2_k3_h3", FULL], [replica, "full_dem_replica_1"]]
    assert e["cycle"] == 8 and math.isfinite(e["settlement_bias_se"])
    assert (tmp_path / "settlement_ensemble.png").stat().st_size > 0
    with open(tmp_path / "ensembles.csv") as f:
        table = list(csv.DictReader(f))
    assert [(r["run"], r["pairs"]) for r in table] == [("shenton_ki2_k3_h3", "2")]
    assert float(table[0]["settlement_bias"]) == pytest.approx(e["settlement_bias"])


def test_a_keep_folder_carries_the_bed_and_the_runs_to_another_folder(study, tmp_path):
    """--keep: the bed, each finished run's record (as its job ends, two jobs at a time
    here) and the tables go to the keep folder;
    a study in an empty folder with that keep folder computes nothing and writes the
    same summary (the configuration error read from the kept residual files); a keep
    folder whose bed is of another config is refused."""
    out, _, _ = study
    first, keep = tmp_path / "first", tmp_path / "keep"
    shutil.copytree(out / "bed", first / "bed")
    for name in (FULL, "shenton_ki2_k3_h3"):
        shutil.copytree(out / "runs" / name, first / "runs" / name)
    args = dict(quick=True, ks=(3,), hs=(3,), k_fixed=3, h_fixed=3)
    summary = run_settlement_study(first, keep=keep, jobs=2, echo=lambda *a: None, **args)
    assert (keep / "bed" / "settled.h5").exists() and (keep / "summary.csv").exists()
    record = json.loads((keep / "runs" / FULL / "study_run.json").read_text())
    assert (keep / "runs" / FULL / record["residual_file"]).exists()
    assert not (keep / "runs" / FULL / "checkpoints").exists()
    lines = []
    again = run_settlement_study(tmp_path / "second", keep=keep, echo=lines.append, **args)
    assert any("bed: reusing" in line for line in lines)
    assert sum("reusing the finished run" in line for line in lines) == 2
    for name, row in summary["runs"].items():
        for key in ("settlement_m", "cpu_s", "settlement_error", "configuration_error",
                    "coordination_error"):
            assert again["runs"][name][key] == row[key], (name, key)
    with pytest.raises(ValueError, match="holds a bed of another config"):
        run_settlement_study(tmp_path / "third", keep=keep, echo=lambda *a: None,
                             overrides={"protocol.stress_amplitude": 3e3}, **args)
    other = tmp_path / "other"
    shutil.copytree(first / "bed", other / "bed")
    perturb(other / "bed" / "settled.h5", 1e-9)         # another settling of the config
    with pytest.raises(ValueError, match="two different settlings"):
        run_settlement_study(other, keep=keep, echo=lambda *a: None, **args)


def test_a_path_marks_its_jumps_and_the_cycles_that_hold_a_correction():
    """Cycles 1-2 computed, a jump 2 -> 5, cycles 6-7 computed, the jump corrected at
    the end of cycle 7 (jump_correction): 7 is "corrected", 5 "extrapolated"."""
    results = {"cycles": [{"cycle": c, "settlement_m": 1e-3 * c} for c in (1, 2, 6, 7)],
               "extrapolations": [{"to_cycle": 5, "settlement_m": 5e-3,
                                   "checked_at_cycle": 7, "correction_m": -1e-4}]}
    assert [(c, src) for c, _, src in settlement_path(results)] == [
        (1, "computed"), (2, "computed"), (5, "extrapolated"), (6, "computed"),
        (7, "corrected")]
    del results["extrapolations"][0]["correction_m"]
    assert settlement_path(results)[-1][2] == "computed"
