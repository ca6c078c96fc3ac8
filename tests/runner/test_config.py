"""Config validation: every bad config is refused naming the field, with exit code 2 and
no traceback; the resolved config round-trips."""
import dataclasses

import pytest
from typer.testing import CliRunner

from graindyn.cli import app
from graindyn.config import Config, ConfigError, dumps, load, validate
from graindyn.config.build import simulation_kwargs
from graindyn.config.models import MaterialSection
from graindyn.core.species import Material
from graindyn.gpu import unavailable

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
    ("unknown integrator", _set(("integrator", "name"), "rk4"), "integrator.name"),
    ("box of wrong dimension", _set(("walls", "container", "lo"), [0, 0]), "walls.container"),
    ("2D gravity with z", _set(("run", "dim"), 2), "run.gravity"),
    ("time step too large", _set(("integrator", "dt"), 1e-4), "integrator.dt"),
    ("law needs a parameter", lambda d: d["materials"][0].pop("restitution"), "restitution"),
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


def test_message_gives_value_and_range(small_config):
    small_config["grains"]["count"] = 0
    with pytest.raises(ConfigError) as err:
        validate(small_config)
    text = str(err.value)
    assert "grains.count = 0" in text and "1..1e8" in text


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


def test_integrator_section_reaches_the_simulation(small_config):
    """Every integrator option is passed on: orientations too (false: not turned)."""
    small_config.setdefault("integrator", {})["orientations"] = False
    kwargs = simulation_kwargs(Config.model_validate(small_config))
    assert kwargs["orientations"] is False
    assert kwargs["check_interval"] == 100


def test_study_command_is_wired():
    result = runner.invoke(app, ["study", "integrators", "--help"])
    assert result.exit_code == 0 and "order-of-accuracy" in result.output


def test_deposition_puts_randomly_inserted_grains_in_cell_order(small_config):
    """Random insertion places grains largest first at random places; the deposition
    hands them to the simulation cell by cell (graindyn.cell_order)."""
    import numpy as np

    from graindyn import cell_order
    from graindyn.protocols.deposition import Deposition

    small_config["protocol"]["insertion"] = "random"
    sim = Deposition(Config.model_validate(small_config)).create(np.random.default_rng(5))
    positions, radii = sim.state.positions, sim.state.radii
    assert not np.all(np.diff(radii) <= 0.0)          # no longer largest first
    np.testing.assert_array_equal(cell_order(positions, 2.2 * radii.max()),
                                  np.arange(radii.size))
