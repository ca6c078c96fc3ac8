"""Runs through the CLI: run directory contents, VTK files read back by meshio,
interruption by SIGTERM and exact resume, checkpoint failures."""
import json
import xml.etree.ElementTree as ET

import h5py
import meshio
import numpy as np
import pytest
from typer.testing import CliRunner

from graindyn.cli import app
from graindyn.engines.soft.gpu import unavailable
from graindyn.output import checkpoint

from cli_runs import cli as _cli, stop_when_logged

runner = CliRunner()


def test_run_directory_holds_everything(finished):
    for name in ("config.toml", "meta.json", "run.log", "series.csv", "results.json",
                 "figures/deposition.png", "checkpoints/checkpoint.h5"):
        assert (finished / name).exists(), name
    meta = json.loads((finished / "meta.json").read_text())
    assert meta["seed"] == 3 and meta["threads"] == 2 and meta["version"]
    assert meta["threading_layer"] in ("omp", "workqueue")       # never TBB (graindyn._threads)
    assert meta["threads_chosen"] == "as asked"
    assert f"threading layer {meta['threading_layer']}" in (finished / "run.log").read_text()
    assert meta["machine"]["cores"] >= 1
    results = json.loads((finished / "results.json").read_text())
    assert results["steps"] > 0 and 0.3 < results["packing_fraction"] < 0.7
    assert 0 < results["cpu_time_this_session_s"] and 0 < results["wall_time_this_session_s"]
    header = (finished / "series.csv").read_text().splitlines()[0]
    assert "time [s]" in header and "force_zlo [N]" in header
    # the resolved config fixes the time step that was suggested
    assert "dt = " in (finished / "config.toml").read_text()


def test_vtk_files_parse_with_their_arrays(finished):
    vtk = finished / "vtk"
    steps = []
    for series, kind, arrays in (("grains", "point", {"radius", "velocity",
                                                      "angular_velocity", "force",
                                                      "material"}),
                                 ("walls", "cell", {"wall", "force"}),
                                 ("contacts", "cell", {"normal_force", "force"})):
        collection = ET.parse(vtk / f"{series}.pvd").getroot()
        files = [d.get("file") for d in collection.iter("DataSet")]
        times = [float(d.get("timestep")) for d in collection.iter("DataSet")]
        assert len(files) >= 3 and times == sorted(times)
        mesh = meshio.read(vtk / files[-1])
        data = mesh.point_data if kind == "point" else mesh.cell_data
        assert arrays <= set(data), (series, set(data))
        steps.append(files)
    grains = meshio.read(vtk / steps[0][-1])
    assert grains.points.shape == (120, 3)
    assert np.all(grains.point_data["radius"] > 0.44e-3)
    contacts = meshio.read(vtk / steps[2][-1])
    assert np.all(contacts.cell_data["normal_force"][0] > 0)  # touching pairs push


def test_plot_redraws_figures(finished):
    figure = finished / "figures" / "deposition.png"
    figure.unlink()
    result = runner.invoke(app, ["plot", str(finished)])
    assert result.exit_code == 0, result.output
    assert figure.exists()


def test_existing_run_directory_is_not_overwritten(finished):
    result = runner.invoke(app, ["run", str(finished / "config.toml"), "--out", str(finished)])
    assert result.exit_code == 2 and "already holds a run" in result.output


def test_sigterm_then_resume_gives_identical_numbers(finished, tmp_path):
    run = tmp_path / "run"
    out = stop_when_logged(_cli("run", finished / "config.toml", "--out", run, "--threads",
                                "2"), run / "run.log", "phase settle")
    assert "resume with" in out
    _, _, step, _ = checkpoint.read(run / "checkpoints" / "checkpoint.h5")
    final = json.loads((finished / "results.json").read_text())["steps"]
    assert 0 < step < final, "the signal should land mid-run"

    proc = _cli("run", "--resume", run)
    out, _ = proc.communicate(timeout=900)
    assert proc.returncode == 0, out
    a, _, step_a, _ = checkpoint.read(finished / "checkpoints" / "checkpoint.h5")
    b, _, step_b, _ = checkpoint.read(run / "checkpoints" / "checkpoint.h5")
    assert step_a == step_b
    for name in ("grains/positions", "grains/velocities", "grains/angular_velocities",
                 "pairs/history", "loop/clock"):
        assert np.array_equal(a[name], b[name]), name
    series_a = (finished / "series.csv").read_text()
    series_b = (run / "series.csv").read_text()
    assert series_a == series_b


def test_truncated_checkpoint_falls_back_to_the_previous(finished, tmp_path):
    folder = tmp_path / "checkpoints"
    folder.mkdir()
    source = finished / "checkpoints"
    (folder / checkpoint.PREVIOUS).write_bytes((source / checkpoint.PREVIOUS).read_bytes())
    data = (source / checkpoint.LATEST).read_bytes()
    (folder / checkpoint.LATEST).write_bytes(data[: len(data) // 2])
    warnings = []
    arrays, meta, step, _ = checkpoint.latest(folder, warn=warnings.append)
    assert warnings and "previous" in warnings[0]
    assert step == checkpoint.read(source / checkpoint.PREVIOUS)[2]
    (folder / checkpoint.PREVIOUS).write_bytes(b"garbage")
    with pytest.raises(checkpoint.CheckpointError, match="no usable checkpoint"):
        checkpoint.latest(folder)


def test_checkpoint_of_another_format_is_refused(finished, tmp_path):
    path = tmp_path / "old.h5"
    path.write_bytes((finished / "checkpoints" / checkpoint.LATEST).read_bytes())
    with h5py.File(path, "a") as f:
        f.attrs["format"] = 999
    with pytest.raises(checkpoint.CheckpointError, match="format 999"):
        checkpoint.read(path)


def test_resume_without_checkpoint_is_a_clear_error(tmp_path, small_config, write_config):
    run = tmp_path / "empty"
    run.mkdir()
    (run / "config.toml").write_text(write_config(small_config).read_text())
    (run / "meta.json").write_text("{}")
    result = runner.invoke(app, ["run", "--resume", str(run)])
    assert result.exit_code == 2 and "no checkpoint" in result.output
    # a run's record without checkpoints (as a sweep's keep folder holds) gets nothing
    assert sorted(p.name for p in run.iterdir()) == ["config.toml", "meta.json"]


def test_resume_of_a_finished_run_leaves_it_as_it_is(finished):
    """--resume of a run that finished says so and changes none of its files (its
    results keep the timing of the session that ran it)."""
    names = ("results.json", "run.log", "series.csv")
    before = {name: (finished / name).read_bytes() for name in names}
    result = runner.invoke(app, ["run", "--resume", str(finished)])
    assert result.exit_code == 0, result.output
    assert "nothing to resume" in result.output
    assert {name: (finished / name).read_bytes() for name in names} == before


def test_plot_and_resume_name_a_folder_that_is_no_run(tmp_path):
    """plot and --resume on a missing folder, a folder without a run, and a sweep's
    folder: one clear message each, exit 2."""
    sweep = tmp_path / "sweep"
    sweep.mkdir()
    (sweep / "points.json").write_text("[]")
    for folder, words in ((tmp_path / "nope", "no such run directory"),
                          (tmp_path, "not a run directory"),
                          (sweep, "a sweep's or a study's folder")):
        for args in (["plot", str(folder)], ["run", "--resume", str(folder)]):
            result = runner.invoke(app, args)
            assert result.exit_code == 2 and words in result.output, (args, result.output)


def test_open_run_reads_a_run_back(finished):
    """graindyn.open_run: the config, meta data, results and series of the files, and the
    engine as the last checkpoint holds it (the same grains to the bit)."""
    import graindyn as gd

    record = gd.open_run(finished)
    assert record.results == json.loads((finished / "results.json").read_text())
    assert record.meta["seed"] == 3 and record.config.run.seed == 3
    time = record.series["time [s]"]
    assert time.size >= 3 and np.all(np.diff(time) > 0)
    engine = record.engine()
    arrays, _, step, t = checkpoint.latest(finished / "checkpoints")
    assert engine.time == t and engine.step == step
    assert np.array_equal(engine.state.positions, arrays["grains/positions"])
    assert len(engine.contacts().normal_force) > 0
    with pytest.raises(FileNotFoundError, match="not a run directory"):
        gd.open_run(finished / "figures")


def test_info_lists_backends_and_cache():
    result = runner.invoke(app, ["info"])
    assert result.exit_code == 0
    for word in ("graindyn", "cpu:", "gpu:", "compile cache", "integrators"):
        assert word in result.output


@pytest.mark.skipif(unavailable() is None, reason="this machine has a usable GPU")
def test_resume_on_a_missing_gpu_is_a_clear_error(finished, tmp_path):
    """A run may be resumed on the other backend (--backend); without a GPU, asking for
    it is refused before anything runs, naming run.backend and the reason."""
    run = tmp_path / "copy"
    run.mkdir()
    for name in ("config.toml", "meta.json"):
        (run / name).write_text((finished / name).read_text())
    (run / "checkpoints").mkdir()
    (run / "checkpoints" / checkpoint.LATEST).write_bytes(
        (finished / "checkpoints" / checkpoint.LATEST).read_bytes())
    result = runner.invoke(app, ["run", "--resume", str(run), "--backend", "gpu"])
    assert result.exit_code == 2 and "run.backend = 'gpu'" in result.output
    assert "Traceback" not in result.output
