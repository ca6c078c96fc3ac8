"""Config validation: every bad config is refused naming the field, with exit code 2 and
no traceback; the resolved config round-trips."""
import copy
import dataclasses
import math
import warnings

import numpy as np
import pytest
from typer.testing import CliRunner

from graindyn.cli import app
from graindyn.config import Config, ConfigError, build, dumps, load, validate
from graindyn.config.models import MaterialSection, material_fields
from graindyn.core.species import ContactModel, Material
from graindyn.engines.soft import loop
from graindyn.engines.soft.gpu import unavailable
from graindyn.physics import registry

runner = CliRunner()


def _set(path, value):
    """A mutation setting data[path...] = value."""
    def mutate(data):
        node = data
        for key in path[:-1]:
            node = node.setdefault(key, {}) if isinstance(node, dict) else node[key]
        node[path[-1]] = value
    return mutate


BAD = [
    ("wrong type", _set(("grains", "count"), "many"), "grains.count"),
    ("out of range", _set(("grains", "count"), -5), "grains.count"),
    ("negative diameter", _set(("grains", "diameter", "min"), -1e-3), "grains.diameter.min"),
    ("unknown key", _set(("grains", "colour"), "red"), "grains.colour"),
    ("unknown section", _set(("solver",), {}), "solver"),
    ("d_min > d_max", _set(("grains", "diameter", "min"), 2e-3), "max"),
    ("poisson ratio", _set(("materials", 0, "poisson_ratio"), 0.6), "materials.0.poisson_ratio"),
    ("restitution > 1", _set(("materials", 0, "restitution"), 1.5), "materials.0.restitution"),
    ("missing wall material", _set(("walls", "material"), "glass"), "walls.material"),
    ("packing above RSA jamming", _set(("protocol", "packing_fraction"), 0.45),
     "protocol.packing_fraction"),
    ("unknown law", _set(("contact", "normal"), "hook"), "hooke"),
    ("unknown integrator", _set(("engine", "integrator"), "rk4"), "engine.integrator"),
    ("box of wrong dimension", _set(("walls", "container", "lo"), [0, 0]), "walls.container"),
    ("2D gravity with z", _set(("run", "dim"), 2), "run.gravity"),
    ("time step too large", _set(("engine", "dt"), 1e-4), "engine.dt"),
    ("law needs a parameter", lambda d: d["materials"][0].pop("restitution"), "restitution"),
    ("boolean for a number", _set(("materials", 0, "density"), True),
     "materials.0.density = True"),
    ("infinite stiffness", _set(("materials", 0, "kn"), math.inf), "materials.0.kn = inf"),
    ("nan in a vector", _set(("run", "gravity"), [0.0, 0.0, math.nan]), "run.gravity.2 = nan"),
    ("negative settling friction", _set(("protocol", "settle_friction"), -0.5),
     "protocol.settle_friction"),
    ("settling friction of a hard-grain engine",
     lambda d: (_set(("protocol", "settle_friction"), 0.0)(d),
                _set(("engine",), {"kind": "event_driven"})(d)),
     "protocol.settle_friction: engine.kind = 'event_driven' cannot change"),
]
if unavailable():     # a machine without a usable GPU refuses the gpu backend
    BAD.append(("gpu backend", _set(("run", "backend"), "gpu"), "run.backend"))


@pytest.mark.parametrize("name, mutate, field", BAD, ids=[b[0] for b in BAD])
def test_bad_config_is_refused_naming_the_field(name, mutate, field, small_config,
                                                 write_config):
    mutate(small_config)
    result = runner.invoke(app, ["validate", str(write_config(small_config))])
    assert result.exit_code == 2, result.output
    assert field in result.output
    assert "Traceback" not in result.output and result.exception is None or \
        isinstance(result.exception, SystemExit)


def test_missing_file_and_bad_toml(tmp_path):
    result = runner.invoke(app, ["validate", str(tmp_path / "nope.toml")])
    assert result.exit_code == 2 and "no such config file" in result.output
    bad = tmp_path / "bad.toml"
    bad.write_text("[grains\ncount = 3")
    result = runner.invoke(app, ["validate", str(bad)])
    assert result.exit_code == 2 and "not valid TOML" in result.output


def test_good_config_validates(small_config, write_config):
    result = runner.invoke(app, ["validate", str(write_config(small_config))])
    assert result.exit_code == 0, result.output
    assert "Rayleigh time" in result.output


def test_sweep_file_validates_every_point(small_config, write_config, tmp_path):
    """A sweep file is checked as a sweep (its base and every point), not refused as a
    config lacking grains; a bad value of one point is named with its point."""
    base = write_config(small_config)
    sweep = tmp_path / "sweep.toml"
    sweep.write_text(f'base = "{base}"\nseeds = [1, 2]\n[[vary]]\n'
                     'parameter = "grains.count"\nvalues = [20, 40]\n')
    result = runner.invoke(app, ["validate", str(sweep)])
    assert result.exit_code == 0, result.output
    assert "a sweep of" in result.output and "6 runs" in result.output
    sweep.write_text(f'base = "{base}"\n[[vary]]\nparameter = "grains.count"\n'
                     'values = [20, 0]\n')
    result = runner.invoke(app, ["validate", str(sweep)])
    assert result.exit_code == 2 and "vary.0 grains.count = 0" in result.output


def test_sweep_file_and_run_config_each_sent_to_its_command(small_config, write_config,
                                                           tmp_path):
    """`graindyn run` on a sweep file and `graindyn sweep` on a run config each say what
    the file is and which command takes it, nothing started."""
    config = write_config(small_config)
    sweep = tmp_path / "sweep.toml"
    sweep.write_text(f'base = "{config}"\n')
    result = runner.invoke(app, ["run", str(sweep), "--out", str(tmp_path / "run")])
    assert result.exit_code == 2 and "graindyn sweep" in result.output, result.output
    result = runner.invoke(app, ["sweep", str(config), "--out", str(tmp_path / "sw")])
    assert result.exit_code == 2 and "graindyn run" in result.output, result.output
    assert not (tmp_path / "run").exists() and not (tmp_path / "sw").exists()


def test_message_gives_value_and_range(small_config):
    small_config["grains"]["count"] = 0
    with pytest.raises(ConfigError) as err:
        validate(small_config)
    text = str(err.value)
    assert "grains.count = 0" in text and "1..1e8" in text


@pytest.mark.parametrize("path, value, kind", [
    (("materials", 0, "density"), True, "a boolean"),
    (("grains", "count"), "120", "a string"),
])
def test_a_number_is_neither_boolean_nor_text(small_config, path, value, kind):
    """pydantic alone would read true as 1 and "120" as 120."""
    _set(path, value)(small_config)
    with pytest.raises(ConfigError) as err:
        validate(small_config)
    where = ".".join(map(str, path))
    assert f"  {where} = {value!r}: Input should be a number, not {kind}  (" in str(err.value)


def test_numbers_are_checked_inside_lists_and_dicts(small_config):
    small_config["contact"]["overrides"] = [{"materials": ["quartz", "steel"],
                                             "values": {"kn": math.inf}}]
    small_config["walls"]["periodic"] = [[False, 0.0, 5e-3]]
    small_config["walls"]["container"]["hi"][2] = "30e-3"
    with pytest.raises(ConfigError) as err:
        validate(small_config)
    text = str(err.value)
    assert "contact.overrides.0.values.kn = inf: Input should be a finite number" in text
    assert "walls.periodic.0.0 = False: Input should be a number, not a boolean" in text
    assert "walls.container.hi.2 = '30e-3': Input should be a number, not a string" in text


def test_a_discriminated_section_is_named_by_its_field(small_config):
    """The kind picks the section (box, oedometer): the message names the field alone and
    gives that field's range."""
    small_config["protocol"] = {"kind": "oedometer", "p0": 0.0}
    with pytest.raises(ConfigError) as err:
        validate(small_config)
    assert "  protocol.p0 = 0.0: Input should be greater than 0  (first vertical stress " \
        "on the piston [Pa]; > 0)" in str(err.value)


def test_resolved_config_round_trips(small_config, tmp_path):
    config = validate(small_config)
    text = dumps(config)
    path = tmp_path / "resolved.toml"
    path.write_text(text)
    again = load(path)
    assert again == config
    assert dumps(again) == text
    # every default is written out
    assert "check_interval" in text and "limit_damping" in text


def test_material_section_mirrors_material():
    """The config and the Python API describe the same materials."""
    assert set(MaterialSection.model_fields) == {f.name for f in dataclasses.fields(Material)}


def test_python_api_takes_the_same_models(small_config):
    config = Config.model_validate(small_config)
    with pytest.raises(ValueError):
        config.grains.count = -1  # assignments are validated too
    with pytest.raises(ValueError):
        config.run.seed = True
    with pytest.raises(ValueError):
        config.materials[0].kn = math.inf


HERTZ = "normal hertz, damping tsuji, tangential mindlin, rolling none, twisting none"
HOOKE = "normal hooke, damping linear, tangential cundall_strack, rolling none, twisting none"
FRICTIONLESS = "normal hertz, damping none, tangential none, rolling none, twisting none"


@pytest.mark.parametrize("contact, quartz, unread", [
    ({}, {"rolling_stiffness": 10.0}, [("quartz", "rolling_stiffness", HERTZ)]),
    ({"normal": "hooke", "damping": "linear", "tangential": "cundall_strack"},
     {"kn": 1e4, "kt": 3e3, "youngs_modulus": 5e9, "poisson_ratio": 0.2},
     [("quartz", "youngs_modulus, poisson_ratio", HOOKE),
      ("steel", "youngs_modulus", HOOKE)]),
    ({"damping": "none", "tangential": "none"}, {},
     [("quartz", "restitution, tangential_damping", FRICTIONLESS),
      ("steel", "restitution", FRICTIONLESS)]),
])
def test_a_material_field_no_law_reads_is_warned_of(small_config, contact, quartz, unread):
    small_config["contact"].update(contact)
    small_config["materials"][0].update(quartz)
    with pytest.warns(UserWarning) as caught:
        validate(small_config)
    assert [str(w.message) for w in caught] == [
        f"material {name!r}: {fields} set but not read by the contact laws ({laws})"
        for name, fields, laws in unread]


def test_fields_the_laws_read_and_defaults_are_not_warned_of(small_config):
    """Nor a field set to its default value, as a resolved config writes every field."""
    small_config["materials"][0]["friction_static"] = 0.5    # the default; mindlin: unread
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        config = validate(small_config)
        validate(config.model_dump())


def test_material_fields_follow_the_pair_table():
    """material_fields names, for each pair-table column, exactly the material fields
    core.species computes it from: a field changed alone changes just those columns
    (the two models fill every column between them)."""
    models = [ContactModel("hertz", "tsuji"), ContactModel("hooke", "linear")]
    base = Material(**{f.name: 0.25 for f in dataclasses.fields(Material) if f.name != "name"})
    for field in MaterialSection.model_fields.keys() - {"name"}:
        changed = Material(**{**dataclasses.asdict(base), field: 0.125})
        columns = set()
        for model in models:
            diff = model.pair_table([changed])[0, 0] != model.pair_table([base])[0, 0]
            columns |= {registry.COLUMNS[k].name for k in np.flatnonzero(diff)}
        assert columns == {c for c in registry.COL if field in material_fields([c])}, field


def test_engine_section_reaches_the_simulation(small_config):
    """Every option of the soft engine is passed on: orientations too (false: not
    turned)."""
    small_config.setdefault("engine", {})["orientations"] = False
    small_config["engine"]["check_interval"] = 50
    config = Config.model_validate(small_config)
    made = build.protocol(config)
    sim = build.engine(config, build.sample(config, made, np.random.default_rng(1)), made)
    assert sim.orientations is False
    assert int(sim.counters[loop.CHECK_INTERVAL]) == 50


def test_study_command_is_wired():
    result = runner.invoke(app, ["study", "integrators", "--help"])
    assert result.exit_code == 0 and "order-of-accuracy" in result.output


def test_deposition_puts_randomly_inserted_grains_in_cell_order(small_config):
    """Random insertion places grains largest first at random places; the deposition
    hands them to the simulation cell by cell (graindyn.cell_order)."""
    import numpy as np

    from graindyn import cell_order

    small_config["protocol"]["insertion"] = "random"
    config = Config.model_validate(small_config)
    state = build.sample(config, build.protocol(config), np.random.default_rng(5))
    positions, radii = state.positions, state.radii
    assert not np.all(np.diff(radii) <= 0.0)          # no longer largest first
    np.testing.assert_array_equal(cell_order(positions, 2.2 * radii.max()),
                                  np.arange(radii.size))


def test_an_older_integrator_section_loads_as_the_engine_section(small_config):
    """[integrator] (name = ...) of an older config is read as [engine] (integrator =
    ...), with a warning that says what to write; both at once, or an engine kind this
    version lacks, are refused with one line naming the section."""
    old = copy.deepcopy(small_config)
    old["integrator"] = {"name": "leap_frog", "dt": 1e-6}
    with pytest.warns(DeprecationWarning, match=r"\[integrator\] is now \[engine\]: write "
                      r"\[engine\] with integrator = 'leap_frog', dt = 1e-06 \(name is now "
                      r"integrator\)"):
        config = validate(old)
    assert (config.engine.kind, config.engine.integrator, config.engine.dt) == \
        ("soft", "leap_frog", 1e-6)
    both = {**old, "engine": {"integrator": "leap_frog"}}
    with pytest.raises(ConfigError, match="both given"):
        validate(both)
    future = {**small_config, "engine": {"kind": "lattice_boltzmann"}}
    with pytest.raises(ConfigError, match="engine.kind = 'lattice_boltzmann' is not an engine "
                       "of this version; engines: soft"):
        validate(future)


@pytest.mark.parametrize("example, kind, motion", [
    ("examples/oedometer.toml", "event_driven", "servo"),
    ("examples/cyclic.toml", "event_driven", "piston")])
def test_an_engine_that_cannot_move_the_protocols_walls_is_refused(example, kind, motion):
    """A protocol whose walls need a motion the engine lacks (hard grains have no servo
    or piston) is refused before any work, naming the engines that offer it."""
    raw = load(example).model_dump()
    raw["engine"] = {"kind": kind}
    with pytest.raises(ConfigError, match=f"engine.kind = '{kind}' offers no {motion} "
                                          "walls, which protocol .* needs; engines that "
                                          "do: soft"):
        validate(raw)


def test_the_contact_laws_are_checked_only_for_an_engine_that_reads_them():
    """Hard grains read the materials' restitution only: a material the soft engine's
    Tsuji damping would refuse (no restitution) runs on the event-driven engine, and is
    refused with the soft one."""
    from graindyn.runner import check

    raw = load("examples/cooling_gas.toml").model_dump(exclude_none=True)
    raw["materials"][0].pop("restitution")
    assert check(validate(raw))["critical_time_s"] is None
    raw["engine"] = {"kind": "soft"}
    with pytest.raises(ConfigError, match="damping 'tsuji' needs restitution"):
        check(validate(raw))


def test_rigid_grains_read_their_materials_friction_without_a_warning(write_config):
    """examples/oedometer_rigid.toml (contact dynamics: no [contact] laws) sets
    friction_static, which the soft engine's default laws would not read: no warning,
    and `graindyn validate` names what rigid grains read instead of the laws."""
    raw = load("examples/oedometer_rigid.toml").model_dump(exclude_none=True)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        validate(raw)
    result = runner.invoke(app, ["validate", "examples/oedometer_rigid.toml"])
    assert result.exit_code == 0, result.output
    assert "contact: the materials' restitution and friction (rigid grains" in result.output
    raw["engine"] = {"kind": "soft"}
    raw["materials"] = [{**m, "youngs_modulus": 1e9} for m in raw["materials"]]
    with pytest.warns(UserWarning, match="friction_static set but not read"):
        validate(raw)
