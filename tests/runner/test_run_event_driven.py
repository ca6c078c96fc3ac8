"""A run of the event-driven engine through the CLI, interrupted by SIGTERM and resumed:
the same numbers as the uninterrupted run."""
import numpy as np
import tomli_w

from graindyn.config import load
from graindyn.output import checkpoint

from cli_runs import cli, stop_when_logged


def _config(folder):
    """examples/cooling_gas.toml made a dense elastic gas of 500 grains (packing
    fraction 0.3) for 20 s: about 1.4e6 collisions, some seconds of wall time."""
    raw = load("examples/cooling_gas.toml").model_dump(exclude_none=True)
    side = (500 * np.pi / 6 * 1e-9 / 0.3) ** (1 / 3)
    raw["grains"]["count"] = 500
    raw["materials"][0]["restitution"] = 1.0
    raw["walls"]["container"]["hi"] = [side] * 3
    raw["walls"]["periodic"] = [[a, 0.0, side] for a in range(3)]
    raw["protocol"].update(duration=20.0, sample_every=0.05)
    raw["output"].update(series_every=0.05, figures=False)
    raw["output"].pop("vtk_every", None)
    path = folder / "gas.toml"
    path.write_text(tomli_w.dumps(raw))
    return path


def test_sigterm_then_resume_gives_identical_numbers(tmp_path):
    config = _config(tmp_path)
    whole = tmp_path / "whole"
    proc = cli("run", config, "--out", whole, "--threads", "1")
    out, _ = proc.communicate(timeout=900)
    assert proc.returncode == 0, out

    run = tmp_path / "run"
    stop_when_logged(cli("run", config, "--out", run, "--threads", "1"), run / "run.log",
                     "phase cool", delay=0.5)
    _, _, step, t = checkpoint.read(run / "checkpoints" / "checkpoint.h5")
    assert 0 < t < 20.0, "the signal should land mid-run"

    proc = cli("run", "--resume", run)
    out, _ = proc.communicate(timeout=900)
    assert proc.returncode == 0, out
    a, _, step_a, _ = checkpoint.read(whole / "checkpoints" / "checkpoint.h5")
    b, _, step_b, _ = checkpoint.read(run / "checkpoints" / "checkpoint.h5")
    assert step_a == step_b
    for name in a:
        assert np.array_equal(a[name], b[name]), name
    for name in ("series.csv", "cooling.csv"):
        assert (whole / name).read_text() == (run / name).read_text(), name
