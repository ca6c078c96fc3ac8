"""benchmarks/gpu_session.py, the one command of a GPU lease, rehearsed under the CUDA
simulator: its stages run in their own processes, each recorded in session.json and
session.log as it ends, and the Tables 2-3 sweep is set up on backend gpu."""
import importlib.util
import json
import pathlib
import subprocess
import sys

import pytest

pytestmark = pytest.mark.skipif(importlib.util.find_spec("numba_cuda") is None,
                                reason="numba-cuda is not installed")

ROOT = pathlib.Path(__file__).resolve().parents[2]


def test_rehearsal_records_each_stage_and_sets_the_sweep_on_the_gpu(tmp_path):
    out, scratch = tmp_path / "out", tmp_path / "scratch"
    run = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "gpu_session.py"),
                          str(out), "--rehearse", "--only", "versions,sweep", "--scratch",
                          str(scratch), "--budget", "120"], capture_output=True, text=True,
                         timeout=300)
    assert run.returncode == 0, run.stderr[-3000:]
    stages = json.loads((out / "session.json").read_text())
    assert [s["stage"] for s in stages] == ["versions", "sweep"]
    assert all(s["exit"] == 0 for s in stages), stages
    log = (out / "session.log").read_text()
    assert "numba-cuda" in log and "reference/seed-1" in log
    base = (scratch / "sweep" / "oedometer.toml").read_text()
    assert '[run]\nbackend = "gpu"\n' in base
    assert (scratch / "sweep" / "oedometer_sweep.toml").is_file()


def test_a_stage_past_the_budget_is_skipped_and_said_so(tmp_path):
    out = tmp_path / "out"
    run = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "gpu_session.py"),
                          str(out), "--rehearse", "--only", "versions", "--budget", "5",
                          "--scratch", str(tmp_path / "scratch")], capture_output=True,
                         text=True, timeout=120)
    assert run.returncode == 0, run.stderr[-3000:]
    (stage,) = json.loads((out / "session.json").read_text())
    assert stage["stage"] == "versions" and "budget" in stage["skipped"]
