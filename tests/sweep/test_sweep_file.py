"""The sweep file: every problem refused with one clear line (exit code 2, no traceback,
before anything runs); the points, their configs and their directory names."""
import json

import pytest
from typer.testing import CliRunner

from graindyn.cli import app
from graindyn.config import ConfigError, dumps, validate
from graindyn.sweep import Sweep, prepare, safe_name, short_names

from .conftest import write_sweep

runner = CliRunner()

FRICTION = {"parameter": "materials.sand.friction_sliding", "values": [0.2, 0.4]}


def _refused(path, *needles):
    """Run ``graindyn sweep PATH`` and check it stops with exit 2 naming every needle."""
    result = runner.invoke(app, ["sweep", str(path), "--out", str(path.parent / "out")])
    assert result.exit_code == 2, result.output
    assert result.exception is None or isinstance(result.exception, SystemExit)
    assert "Traceback" not in result.output
    for needle in needles:
        assert needle in result.output, (needle, result.output)
    assert not (path.parent / "out").exists(), "nothing may start on a bad sweep file"
    return result.output


BAD = [
    ("unknown top-level key", {"seeds": [1], "colour": "red", "vary": [FRICTION]},
     ["colour: unknown key"]),
    ("unknown key in vary", {"vary": [{**FRICTION, "unit": "-"}]}, ["vary.0.unit: unknown key"]),
    ("display of another length", {"vary": [{**FRICTION, "display": [1, 2, 3]}]},
     ["vary.0", "display has 3 entries but values has 2"]),
    ("no values", {"vary": [{**FRICTION, "values": []}]}, ["vary.0.values"]),
    ("value twice", {"vary": [{**FRICTION, "values": [0.2, 0.2]}]}, ["listed twice"]),
    ("negative seed", {"seeds": [1, -2]}, ["seeds", "must be >= 0"]),
    ("seed twice", {"seeds": [1, 1]}, ["seeds", "listed twice"]),
    ("seed is set per point", {"vary": [{"parameter": "run.seed", "values": [1, 2]}]},
     ["run.seed", "seeds"]),
    ("parameter twice", {"vary": [FRICTION, FRICTION]}, ["vary.1.parameter",
                                                         "already varied in vary.0"]),
    ("bad field in the path", {"vary": [{**FRICTION,
                                         "parameter": "materials.sand.frictoin_sliding"}]},
     ["vary.0.parameter = 'materials.sand.frictoin_sliding'", "no field 'frictoin_sliding'",
      "friction_sliding"]),
    ("unknown material", {"vary": [{**FRICTION, "parameter": "materials.snad.density"}]},
     ["no item 'snad'", "sand, steel"]),
    ("unknown section", {"vary": [{**FRICTION, "parameter": "solver.tolerance"}]},
     ["the config has no field 'solver'"]),
    ("a section is not a value", {"vary": [{**FRICTION, "parameter": "materials.sand"}]},
     ["materials.sand is a section"]),
    ("invalid value, named with its point",
     {"vary": [{**FRICTION, "values": [0.2, -0.1]}]},
     ["vary.0 materials.sand.friction_sliding = -0.1", "friction_sliding = -0.1",
      "greater than or equal to 0"]),
    ("wrong type of value", {"vary": [{"parameter": "grains.count", "values": ["many"]}]},
     ["grains.count = 'many'"]),
    ("value that breaks a cross-check",
     {"vary": [{"parameter": "contact.tangential", "values": ["mindlin", "stick"]}]},
     ["contact.tangential = 'stick'"]),
    ("override of an unknown field", {"overrides": {"engine.skni": 1e-4}},
     ["overrides.engine.skni", "no field 'skni'"]),
    ("override with a bad value", {"overrides": {"engine.overlap_limit": -1.0}},
     ["overrides", "overlap_limit = -1.0"]),
    ("override of the seed", {"overrides": {"run.seed": 4}}, ["run.seed", "seeds"]),
    ("override of a varied parameter",
     {"overrides": {FRICTION["parameter"]: 0.3}, "vary": [FRICTION]},
     ["vary.0.parameter", "also in overrides"]),
    ("time step too large for a value",
     {"vary": [{"parameter": "engine.dt", "values": [1e-7, 1e-3]}]},
     ["engine.dt = 0.001", "engine.dt"]),
]


@pytest.mark.parametrize("name, sweep, needles", BAD, ids=[b[0] for b in BAD])
def test_bad_sweep_file_is_refused(name, sweep, needles, tmp_path):
    _refused(write_sweep(tmp_path, sweep), *needles)


def test_every_bad_value_is_listed_at_once(tmp_path):
    path = write_sweep(tmp_path, {"vary": [
        {**FRICTION, "values": [-1.0, 0.3]},
        {"parameter": "materials.sand.youngs_modulus", "values": [1e8, 0.0]}]})
    out = _refused(path, "2 problem(s)", "friction_sliding = -1.0", "youngs_modulus = 0.0")
    assert "= 0.3" not in out and "= 100000000.0" not in out   # the good values


def test_missing_files_and_bad_toml(tmp_path):
    _refused(tmp_path / "nope.toml", "no such sweep file")
    path = write_sweep(tmp_path, {})
    (tmp_path / "base.toml").unlink()
    _refused(path, "base = 'base.toml'", "no such config file")
    bad = tmp_path / "bad.toml"
    bad.write_text("base = 'base.toml'\n[[vary]\n")
    _refused(bad, "not valid TOML")


def test_bad_base_config_is_named(tmp_path, tiny):
    tiny["grains"]["count"] = 0
    _refused(write_sweep(tmp_path, {}, base=tiny), "base.toml", "grains.count = 0")


def test_workers_with_a_scheduler_is_refused(tmp_path):
    path = write_sweep(tmp_path, {})
    result = runner.invoke(app, ["sweep", str(path), "--scheduler", "tcp://127.0.0.1:1",
                                 "--workers", "2"])
    assert result.exit_code == 2 and "--workers" in result.output


def test_points_configs_and_names(tmp_path):
    path = write_sweep(tmp_path, {"seeds": [1, 7], "vary": [
        {"parameter": "materials.sand.friction_sliding", "values": [0.2, 0.5],
         "label": "mu_k"},
        {"parameter": "materials.sand.youngs_modulus", "values": [1.125e8, 1.8e10],
         "label": "V [GPa]", "display": [0.1125, 18.0]},
        {"parameter": "materials.steel.youngs_modulus", "values": [1e9]},
        {"parameter": "engine.overlap_limit", "values": [1e-6]},
        {"parameter": "contact.tangential", "values": ["coulomb"]},
        {"parameter": "run.gravity", "values": [[0.0, 0.0, -1.62]]}]})
    sweep = Sweep.load(path)
    names = [p.name for p in sweep.points]
    assert names[:2] == ["reference/seed-1", "reference/seed-7"]
    assert names[2:] == [
        "friction_sliding=0.2/seed-1", "friction_sliding=0.2/seed-7",
        # 0.5 is the base value: the reference run itself, not computed twice
        "reference/seed-1", "reference/seed-7",
        "sand.youngs_modulus=1.125e8/seed-1", "sand.youngs_modulus=1.125e8/seed-7",
        "sand.youngs_modulus=1.8e10/seed-1", "sand.youngs_modulus=1.8e10/seed-7",
        "steel.youngs_modulus=1e9/seed-1", "steel.youngs_modulus=1e9/seed-7",
        "overlap_limit=1e-6/seed-1", "overlap_limit=1e-6/seed-7",
        "tangential=coulomb/seed-1", "tangential=coulomb/seed-7",
        "gravity=0,0,-1.62/seed-1", "gravity=0,0,-1.62/seed-7"]
    assert len(sweep.runs) == len(set(names)) == 16
    by_name = {(p.parameter, p.name): p for p in sweep.points}
    point = by_name[("materials.sand.youngs_modulus", "sand.youngs_modulus=1.8e10/seed-7")]
    assert point.config.materials[0].youngs_modulus == 1.8e10
    assert point.config.run.seed == 7 and point.seed == 7
    assert point.label == "V [GPa]" and point.display == 18.0
    assert point.base_value == 1e8            # the default of the field
    assert point.config.materials[1].youngs_modulus == 2e9      # steel untouched
    alias = by_name[("materials.sand.friction_sliding", "reference/seed-1")]
    assert alias.is_reference and alias.value == 0.5 and alias.label == "mu_k"
    gravity = by_name[("run.gravity", "gravity=0,0,-1.62/seed-1")]
    assert gravity.config.run.gravity == (0.0, 0.0, -1.62)
    reference = sweep.points[0]
    assert reference.parameter is None
    assert reference.config.model_dump() == validate(
        {**json.loads(sweep.base.model_dump_json()), "run": {
            **sweep.base.run.model_dump(), "seed": 1}}).model_dump()


def test_overrides_change_every_point_the_reference_included(tmp_path):
    sweep = Sweep.load(write_sweep(tmp_path, {"overrides": {
        "engine.overlap_limit": 0.05, "materials.steel.youngs_modulus": 3e9},
        "vary": [FRICTION]}))
    assert len(sweep.points) == 3
    for p in sweep.points:
        assert p.config.engine.overlap_limit == 0.05
        assert p.config.materials[1].youngs_modulus == 3e9
    assert sweep.base.engine.overlap_limit == 0.05
    assert [p.config.materials[0].friction_sliding for p in sweep.points] == [0.5, 0.2, 0.4]


def test_default_seed_is_the_base_seed(tmp_path):
    sweep = Sweep.load(write_sweep(tmp_path, {"vary": [FRICTION]}))
    assert [p.name for p in sweep.points] == [
        "reference/seed-3", "friction_sliding=0.2/seed-3", "friction_sliding=0.4/seed-3"]


def test_names_are_safe_and_short():
    assert safe_name("a b/c:d*e") == "a_b_c_d_e"
    assert safe_name("..") == "_"
    long = safe_name("x" * 300)
    assert len(long) <= 80 and long != safe_name("x" * 299)
    assert short_names(["a.b.c", "a.d.c", "a.e"]) == {"a.b.c": "b.c", "a.d.c": "d.c",
                                                      "a.e": "e"}


def test_dry_run_lists_the_points(tmp_path):
    path = write_sweep(tmp_path, {"seeds": [1, 2], "vary": [FRICTION]})
    result = runner.invoke(app, ["sweep", str(path), "--dry-run"])
    assert result.exit_code == 0, result.output
    assert "6 points, 6 runs" in result.output
    assert "friction_sliding=0.4/seed-2" in result.output


def test_prepare_copies_the_files_and_refuses_a_foreign_run(tmp_path, tiny):
    sweep = Sweep.load(write_sweep(tmp_path, {"vary": [FRICTION]}))
    out = tmp_path / "out"
    prepare(sweep, out)
    assert (out / "sweep.toml").read_text() == sweep.path.read_text()
    assert (out / "base.toml").read_text() == (tmp_path / "base.toml").read_text()
    listed = json.loads((out / "points.json").read_text())
    assert [p["directory"] for p in listed] == [p.name for p in sweep.points]
    # a run directory written by another config (here friction 0.3 instead of 0.2)
    tiny["materials"][0]["friction_sliding"] = 0.3
    tiny["run"]["seed"] = 3
    folder = out / "friction_sliding=0.2" / "seed-3"
    folder.mkdir(parents=True)
    (folder / "config.toml").write_text(dumps(validate(tiny)))
    with pytest.raises(ConfigError, match=r"materials\.0\.friction_sliding: 0\.3 there, "
                                          r"0\.2 in the sweep"):
        prepare(sweep, out)
    # the same config with the fields the runner fills in (dt, skin, threads) matches
    tiny["materials"][0]["friction_sliding"] = 0.2
    tiny["engine"] = {"dt": 2e-6, "skin": 1e-4}
    tiny["run"]["threads"] = 2
    (folder / "config.toml").write_text(dumps(validate(tiny)))
    prepare(sweep, out)


def test_values_with_the_same_safe_name_get_distinct_folders(tmp_path):
    sweep = Sweep.load(write_sweep(tmp_path, {"seeds": [1], "vary": [
        {"parameter": "run.name", "values": ["a b", "a_b", "a/b"]}]}))
    assert [p.name for p in sweep.points[1:]] == [
        "name=a_b/seed-1", "name=a_b-1/seed-1", "name=a_b-2/seed-1"]
