"""Sweeps that run: one point's task (skip, resume, start, fail), a local-cluster sweep
interrupted by Ctrl-C and resumed by rerunning the same command (with a failing point),
and a sweep on a Dask scheduler given by address."""
import contextlib
import json
import os
import shutil
import signal
import time

import numpy as np
import pytest
from typer.testing import CliRunner

from graindyn import runner as runs
from graindyn import sweep as sweeps
from graindyn.cli import app
from graindyn.sweep import Sweep, run_point

from .conftest import cli, write_sweep

runner = CliRunner()


# ---------------------------------------------------------------- one point's task
@pytest.fixture
def calls(monkeypatch):
    """runner.execute / runner.resume replaced by recorders (nothing simulates)."""
    log = []

    def execute(config, out, show_progress=True, echo=print):
        log.append(("execute", out, config.run.threads, show_progress))
        out.mkdir(parents=True, exist_ok=True)
        (out / "results.json").write_text("{}")

    def resume(out, show_progress=True, echo=print, threads=None):
        log.append(("resume", out, threads, show_progress))

    monkeypatch.setattr(runs, "execute", execute)
    monkeypatch.setattr(runs, "resume", resume)
    return log


@pytest.fixture
def point(tmp_path):
    sweep = Sweep.load(write_sweep(tmp_path, {"seeds": [1]}))
    return sweep.points[0].config, tmp_path / "out" / "reference" / "seed-1"


def test_runs_start_interrupted_first_then_seed_by_seed(tmp_path):
    """An interrupted run (a checkpoint) goes first, then every point's first seed
    before any point's second, in the sweep file's order of seeds and points."""
    sweep = Sweep.load(write_sweep(tmp_path, {"seeds": [3, 1], "vary": [
        {"parameter": "materials.sand.friction_sliding", "values": [0.2, 0.4]}]}))
    out = tmp_path / "out"
    interrupted = out / "friction_sliding=0.4" / "seed-1" / "checkpoints"
    interrupted.mkdir(parents=True)
    (interrupted / "checkpoint.h5").write_bytes(b"x")
    order = sweeps.run_order(sweep.runs, out, [3, 1])
    assert [p.name for p in order] == [
        "friction_sliding=0.4/seed-1", "reference/seed-3", "friction_sliding=0.2/seed-3",
        "friction_sliding=0.4/seed-3", "reference/seed-1", "friction_sliding=0.2/seed-1"]


def test_task_skips_a_finished_point(calls, point):
    config, folder = point
    folder.mkdir(parents=True)
    (folder / "results.json").write_text('{"steps": 3}')
    outcome = run_point(config, folder, 2)
    assert outcome["status"] == "finished" and calls == []


def test_task_resumes_from_a_checkpoint(calls, point):
    config, folder = point
    (folder / "checkpoints").mkdir(parents=True)
    (folder / "checkpoints" / "checkpoint.h5").write_bytes(b"x")
    (folder / "results.json").write_text('{"steps": ')       # cut short by a kill
    outcome = run_point(config, folder, 2)
    assert calls == [("resume", folder, 2, False)] and outcome["how"] == "resumed"


def test_task_restarts_a_run_without_checkpoint(calls, point):
    config, folder = point
    folder.mkdir(parents=True)
    (folder / "config.toml").write_text("leftover")
    (folder / "error.txt").write_text("old failure")
    outcome = run_point(config, folder, 3)
    assert calls == [("execute", folder, 3, False)] and outcome["how"] == "started"
    assert not (folder / "config.toml").exists() and not (folder / "error.txt").exists()
    assert config.run.threads == 0            # the point's config itself is untouched


def test_task_records_a_failure(monkeypatch, point):
    config, folder = point

    def execute(config, out, **kw):
        raise FloatingPointError("the grains flew apart")

    monkeypatch.setattr(runs, "execute", execute)
    outcome = run_point(config, folder, 1)
    assert outcome["status"] == "failed"
    assert outcome["error"] == "FloatingPointError: the grains flew apart"
    text = (folder / "error.txt").read_text()
    assert text.startswith("FloatingPointError: the grains flew apart")
    assert "Traceback" in text and "raise FloatingPointError" in text


def test_task_leaves_foreign_files_alone(calls, point):
    config, folder = point
    folder.mkdir(parents=True)
    (folder / "thesis.tex").write_text("precious")
    outcome = run_point(config, folder, 1)
    assert outcome["status"] == "failed" and "not a graindyn run" in outcome["error"]
    assert (folder / "thesis.tex").read_text() == "precious" and calls == []


# ---------------------------------------------------------------- interrupted, resumed
def _run_folder(root, seed):
    folder = root / "reference" / f"seed-{seed}"
    folder.mkdir(parents=True)
    return folder


def test_status_says_where_each_run_stands_and_writes_nothing(tmp_path):
    """``--status``: a finished run (its wall time), one recorded only in the keep
    folder, a started run (the last simulated time its log names, its last line that is
    not a checkpoint, the rate between the last two checkpoints of its latest session),
    a failed run and one not started; no file is written or changed."""
    path = write_sweep(tmp_path, {"seeds": [1, 2, 3, 4, 5]})
    sweep = Sweep.load(path)
    out, keep = tmp_path / "out", tmp_path / "keep"
    (_run_folder(out, 1) / "results.json").write_text('{"wall_time_this_session_s": 754.0}')
    (_run_folder(keep, 2) / "results.json").write_text('{"wall_time_this_session_s": 30.0}')
    log = _run_folder(out, 3) / "run.log"
    log.write_text("\n".join([
        "2026-12-06 01:00:00,000 start: 30 grains, soft engine, dt = 1e-07 s",
        "2026-12-06 01:00:00,100 checkpoint at t = 0 s (step 0)",
        "2026-12-06 01:00:00,100 phase settle from t = 0 s",
        "2026-12-06 01:10:00,000 checkpoint at t = 0.02 s (step 200000)",
        "2026-12-06 02:00:00,000 resume from t = 0.02 s (step 200000), 1 threads",
        "2026-12-06 02:00:01,000 phase load from t = 0.02 s",
        "2026-12-06 02:06:00,000 checkpoint at t = 0.03 s (step 300000)",
        "2026-12-06 02:12:00,000 checkpoint at t = 0.04 s (step 400000)",
        "2026-12-06 02:13:00,000 level 2 (loading) p = 5e+04 Pa: at rest at t = 0.041 s",
        "a line the logger did not write, t = 9 s"]) + "\n")
    (_run_folder(out, 4) / "error.txt").write_text("OverlapError: an overlap exceeded\nmore")
    before = {f: f.stat().st_mtime_ns for f in tmp_path.rglob("*")}

    rows = sweeps.standing(sweep, out, keep=keep, now=log.stat().st_mtime + 90.0)
    assert [r["name"] for r in rows] == [f"reference/seed-{s}" for s in range(1, 6)]
    assert rows[0] == {"name": "reference/seed-1", "state": "finished", "wall_s": 754.0}
    assert rows[1] == {"name": "reference/seed-2", "state": "finished", "wall_s": 30.0,
                       "kept": True}
    started = rows[2]
    assert started["state"] == "started"
    assert started["simulated_s"] == 0.041
    assert started["news"] == "level 2 (loading) p = 5e+04 Pa: at rest at t = 0.041 s"
    assert started["quiet_s"] == pytest.approx(90.0)
    assert started["rate"] == pytest.approx(0.1)     # 0.01 s in 6 min, not across sessions
    assert rows[3] == {"name": "reference/seed-4", "state": "failed",
                       "error": "OverlapError: an overlap exceeded"}
    assert rows[4] == {"name": "reference/seed-5", "state": "not started"}

    result = runner.invoke(app, ["sweep", str(path), "--out", str(out), "--keep", str(keep),
                                 "--status"])
    assert result.exit_code == 0, result.output
    assert "5 runs, 2 finished, 1 started, 1 failed, 1 not started" in result.output
    assert "finished, last session 13 min of wall time" in result.output
    assert "finished (recorded in the keep folder), last session 30 s" in result.output
    assert "started: t = 0.041 s (0.1 simulated s per wall hour), logged" in result.output
    assert "FAILED: OverlapError: an overlap exceeded" in result.output
    assert {f: f.stat().st_mtime_ns for f in tmp_path.rglob("*")} == before


@pytest.fixture(scope="module")
def interrupted(tmp_path_factory):
    """``graindyn sweep`` on a local cluster of one worker: the reference (short), a long
    point (protocol.max_time = 1 s: long enough to be caught running on a fast machine)
    and a point that breaks (overlap limit 1e-6).
    Ctrl-C once the reference has finished and the long point has written two
    checkpoints; then the same command again."""
    folder = tmp_path_factory.mktemp("interrupted")
    path = write_sweep(folder, {"seeds": [1], "vary": [
        {"parameter": "protocol.max_time", "values": [1.0]},
        {"parameter": "engine.overlap_limit", "values": [1e-6]}]})
    out = folder / "out"
    reference, long = out / "reference" / "seed-1", out / "max_time=1" / "seed-1"
    proc = cli("sweep", path, "--out", out, "--workers", "1")
    try:
        deadline = time.time() + 300
        while time.time() < deadline and proc.poll() is None and not (
                (reference / "results.json").exists()
                and (long / "checkpoints" / "checkpoint.prev.h5").exists()):
            time.sleep(0.02)
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGINT)
        first, _ = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    state = {"code": proc.returncode, "long_finished": (long / "results.json").exists(),
             "mtime": (reference / "results.json").stat().st_mtime_ns,
             "reference": (reference / "results.json").read_text()}
    proc = cli("sweep", path, "--out", out, "--workers", "1")
    second, _ = proc.communicate(timeout=600)
    return {"out": out, "first": first, "second": second, "code": proc.returncode,
            "before": state}


def test_interrupted_sweep_resumes_without_recomputing(interrupted):
    before, out = interrupted["before"], interrupted["out"]
    assert before["code"] == 130, interrupted["first"]
    assert "rerun the same command" in interrupted["first"]
    assert "Traceback" not in interrupted["first"]
    assert not before["long_finished"], "Ctrl-C should land while the long point runs"
    reference = out / "reference" / "seed-1" / "results.json"
    assert reference.stat().st_mtime_ns == before["mtime"]
    assert reference.read_text() == before["reference"]
    assert "1 finished earlier, 2 to run" in interrupted["second"]
    assert "finished reference" not in interrupted["second"]
    long = out / "max_time=1" / "seed-1"
    assert "resume from t = " in (long / "run.log").read_text()
    assert "finished max_time=1/seed-1 (resumed" in interrupted["second"]
    results = json.loads((long / "results.json").read_text())
    assert results["time_s"] == pytest.approx(1.0, rel=1e-3)


def test_failed_point_is_reported_and_the_others_finish(interrupted):
    out, second = interrupted["out"], interrupted["second"]
    assert interrupted["code"] == 1, second
    assert "Traceback" not in second
    assert "FAILED overlap_limit=1e-6/seed-1: OverlapError: an overlap exceeded" in second
    assert "2 of 3 runs finished" in second and "1 run(s) failed" in second
    error = (out / "overlap_limit=1e-6" / "seed-1" / "error.txt").read_text()
    assert error.startswith("OverlapError") and "Traceback" in error
    summary = json.loads((out / "summary.json").read_text())
    assert summary["runs"] == {"finished": 2, "failed": 1, "pending": 0}
    rows = (out / "summary.csv").read_text().splitlines()
    assert len(rows) == 4 and "overlap_limit=1e-6/seed-1" in rows[3]
    assert ",failed," in rows[3] and ",finished," in rows[1] and ",finished," in rows[2]
    for name in ("sweep.toml", "base.toml", "points.json"):
        assert (out / name).exists()


# ---------------------------------------------------------------- a given scheduler
@pytest.fixture(scope="module")
def scheduler():
    """The address of a running Dask scheduler with one worker process."""
    from distributed import LocalCluster

    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                      dashboard_address=":0") as cluster:
        yield cluster.scheduler_address


def test_sweep_on_a_scheduler_combines_the_seeds(scheduler, tmp_path):
    path = write_sweep(tmp_path, {"seeds": [1, 2]})
    out = tmp_path / "out"
    result = runner.invoke(app, ["sweep", str(path), "--out", str(out), "--scheduler",
                                 scheduler, "--threads-per-worker", "1"])
    assert result.exit_code == 0, result.output
    assert f"the Dask scheduler at {scheduler}" in result.output
    assert "[2/2] finished" in result.output
    results = [json.loads((out / "reference" / f"seed-{s}" / "results.json").read_text())
               for s in (1, 2)]
    meta = json.loads((out / "reference" / "seed-2" / "meta.json").read_text())
    assert meta["seed"] == 2 and meta["threads"] == 1 and results[1]["threads"] == 1
    fractions = [r["packing_fraction"] for r in results]
    assert fractions[0] != fractions[1]       # two seeds, two samples
    group = json.loads((out / "summary.json").read_text())["groups"][0]
    assert group["mean"]["packing_fraction"] == pytest.approx(np.mean(fractions))
    assert group["std"]["packing_fraction"] == pytest.approx(np.std(fractions, ddof=1))
    # the same command again computes nothing
    again = runner.invoke(app, ["sweep", str(path), "--out", str(out), "--scheduler",
                                scheduler])
    assert again.exit_code == 0 and "2 finished earlier, 0 to run" in again.output
    assert "running on" not in again.output


def test_keep_folder_records_the_runs_and_a_new_directory_starts_from_it(scheduler,
                                                                        tmp_path):
    """--keep: each finished run's record (config, meta, results; no checkpoints) and
    the summaries land in the keep folder; a fresh sweep directory with the same keep
    folder runs nothing and summarizes the same numbers; records of another config are
    refused before anything is copied."""
    path = write_sweep(tmp_path, {"seeds": [1, 2]})
    keep = tmp_path / "kept"
    args = ["sweep", str(path), "--scheduler", scheduler, "--keep", str(keep)]
    first = runner.invoke(app, args + ["--out", str(tmp_path / "out1")])
    assert first.exit_code == 0, first.output
    for seed in (1, 2):
        record = keep / "reference" / f"seed-{seed}"
        assert sorted(p.name for p in record.iterdir()) == sorted(sweeps.RECORD)
    for name in ("sweep.toml", "base.toml", "points.json", "summary.json", "summary.csv"):
        assert (keep / name).is_file()
    second = runner.invoke(app, args + ["--out", str(tmp_path / "out2")])
    assert second.exit_code == 0, second.output
    assert "2 finished earlier (2 of them taken from" in second.output
    assert "running on" not in second.output
    summaries = [json.loads((tmp_path / out / "summary.json").read_text())["groups"]
                 for out in ("out1", "out2")]
    assert summaries[0] == summaries[1]
    # --summarize: the summaries of what is finished, nothing run
    shutil.rmtree(keep / "reference" / "seed-2")
    partial = runner.invoke(app, ["sweep", str(path), "--keep", str(keep), "--summarize",
                                  "--out", str(tmp_path / "out4")])
    assert partial.exit_code == 0, partial.output
    assert "1 finished earlier (1 of them taken from" in partial.output
    assert "running on" not in partial.output
    assert not (tmp_path / "out4" / "reference" / "seed-2").exists()
    summary = json.loads((tmp_path / "out4" / "summary.json").read_text())
    assert summary["runs"] == {"finished": 1, "failed": 0, "pending": 1}
    other = write_sweep(tmp_path / "other", {"seeds": [1],
                                             "overrides": {"protocol.max_time": 0.02}})
    refused = runner.invoke(app, ["sweep", str(other), "--scheduler", scheduler, "--keep",
                                  str(keep), "--out", str(tmp_path / "out3")])
    assert refused.exit_code == 2
    assert "record(s) do not match the sweep" in refused.output
    assert "protocol.max_time" in refused.output
    assert not (tmp_path / "out3" / "reference").exists()


def test_seeds_and_points_run_a_part_of_the_sweep_first(scheduler, tmp_path):
    """--seeds 2 runs seed 2 alone (exit 0: every run asked for finished) and leaves
    seed 1 pending in the summary; the whole sweep then runs seed 1 alone; a seed or a
    point the sweep does not have is refused before anything runs."""
    path = write_sweep(tmp_path, {"seeds": [1, 2]})
    out = tmp_path / "out"
    args = ["sweep", str(path), "--out", str(out), "--scheduler", scheduler]
    part = runner.invoke(app, args + ["--seeds", "2", "--points", "reference"])
    assert part.exit_code == 0, part.output
    assert "1 of the 2 others selected" in part.output
    assert (out / "reference" / "seed-2" / "results.json").is_file()
    assert not (out / "reference" / "seed-1").exists()
    summary = json.loads((out / "summary.json").read_text())
    assert summary["runs"] == {"finished": 1, "failed": 0, "pending": 1}
    rest = runner.invoke(app, args)
    assert rest.exit_code == 0, rest.output
    assert "1 finished earlier" in rest.output and "[1/1] finished reference/seed-1" \
        in rest.output
    for bad in (["--seeds", "7"], ["--points", "nowhere"]):
        refused = runner.invoke(app, args + bad)
        assert refused.exit_code == 2 and "has no" in refused.output, refused.output


def test_unreachable_scheduler_is_a_clear_error(tmp_path, monkeypatch):
    monkeypatch.setattr(sweeps, "CONNECT_TIMEOUT", "1s")
    path = write_sweep(tmp_path, {"seeds": [1]})
    result = runner.invoke(app, ["sweep", str(path), "--out", str(tmp_path / "out"),
                                 "--scheduler", "tcp://127.0.0.1:9"])
    assert result.exit_code == 2 and "cannot connect" in result.output, result.output
