"""Every number of every example config, replaced by true, false, inf, -inf, nan and its
own text, is refused with one line naming the field, the value and the allowed range;
the sweep files' numbers likewise.  Validation only: nothing is simulated."""
import copy
import math
import pathlib
import tomllib
import typing

import pytest
import tomli_w
from pydantic import BaseModel

from graindyn.config import ConfigError, validate
from graindyn.config.models import Section
from graindyn.sweep import Sweep

EXAMPLES = pathlib.Path(__file__).parents[2] / "examples"
FILES = {p.name: tomllib.loads(p.read_text()) for p in sorted(EXAMPLES.glob("*.toml"))}
SWEEPS = {name: data for name, data in FILES.items() if "base" in data}


def _numbers(node, path=()):
    """(path, value) of every int and float in a TOML document (booleans are not)."""
    if isinstance(node, dict):
        items = node.items()
    elif isinstance(node, list):
        items = enumerate(node)
    else:
        number = isinstance(node, (int, float)) and not isinstance(node, bool)
        return [(path, node)] if number else []
    return [leaf for key, value in items for leaf in _numbers(value, path + (key,))]


def _replaced(data, path, value):
    """A deep copy of ``data`` with the leaf at ``path`` set to ``value``."""
    data = copy.deepcopy(data)
    node = data
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] = value
    return data


NON_FINITE = (math.inf, -math.inf, math.nan)
NOT_NUMBERS = (True, False, *NON_FINITE)


def _bad(value):
    """What a number must never be: a boolean, infinite, nan, or a string (its text)."""
    return [*NOT_NUMBERS, str(value)]


def _field(config, path):
    """(section class, field name) of the number at ``path`` in a validated Config."""
    node = config
    for key in path:
        if isinstance(node, BaseModel):
            owner, name = type(node), key
            node = getattr(node, key)
        else:
            node = node[key]
    return owner, name


def _config_path(config, parameter):
    """The path in Config of a sweep parameter, whose list items go by name
    (materials.sand.kn: ("materials", 0, "kn"))."""
    node, path = config, []
    for part in parameter.split("."):
        if isinstance(node, list):
            part = [item.name for item in node].index(part)
            node = node[part]
        else:
            node = getattr(node, part)
        path.append(part)
    return tuple(path)


def _refusal(err, source):
    """The one problem line of a ConfigError about ``source``."""
    header, *problems = str(err.value).splitlines()
    assert header == f"{source}: 1 problem(s)" and len(problems) == 1, str(err.value)
    return problems[0]


# each config example resolved (every default written out, so the defaults are fuzzed
# too), and deposition_3d with what no example sets: planes with a motion, a pair
# override, a periodic direction, a normal diameter distribution, a skin
_EXTENDED = copy.deepcopy(FILES["deposition_3d.toml"])
_EXTENDED["grains"]["diameter"] = {"distribution": "normal", "mean": 1e-3, "std": 1e-4}
_EXTENDED["contact"]["overrides"] = [{"materials": ["quartz", "steel"],
                                      "values": {"friction_sliding": 0.3}}]
_EXTENDED["walls"]["planes"] = [{"name": "lid", "point": [0.0, 0.0, 0.05],
                                 "normal": [0.0, 0.0, -1.0], "area": 1e-4,
                                 "motion": {"kind": "sinusoid", "amplitude": 1e-3}}]
_EXTENDED["walls"]["periodic"] = [[0, 0.0, 10e-3]]
_EXTENDED["engine"] = {"skin": 1e-4}
_SOURCES = {**{name: data for name, data in FILES.items() if name not in SWEEPS},
            "deposition_3d.toml (extended)": _EXTENDED}


def _resolved(data, name):
    """(the resolved config dict, the Config) of a config dict."""
    config = validate(data, name)
    return config.model_dump(mode="json", exclude_none=True), config


CONFIGS = {name: _resolved(data, name) for name, data in _SOURCES.items()}
CASES = [(name, path, value) for name, (data, _) in CONFIGS.items()
         for path, value in _numbers(data)]


@pytest.mark.parametrize("name, path, value", CASES,
                         ids=[f"{n}:{'.'.join(map(str, p))}" for n, p, _ in CASES])
def test_a_config_number_is_a_finite_number(name, path, value):
    data, config = CONFIGS[name]
    owner, field = _field(config, path)
    where = ".".join(map(str, path))
    for bad in _bad(value):
        with pytest.raises(ConfigError) as err:
            validate(_replaced(data, path, bad), name)
        line = _refusal(err, name)
        assert line.startswith(f"  {where} = {bad!r}: "), line
        assert line.endswith(f"  ({owner.model_fields[field].description})"), line


def _holds_numbers(annotation):
    """True for an annotation with int or float leaves (Float, tuple[Float, ...], ...)."""
    return annotation in (int, float) or any(map(_holds_numbers,
                                                 typing.get_args(annotation)))


def _sections(cls=Section):
    """The section classes that are used as they are (no subclass of their own)."""
    subclasses = cls.__subclasses__()
    return [cls] if not subclasses else [s for sub in subclasses for s in _sections(sub)]


def test_the_fuzz_reaches_every_number_field():
    """A number field of a run config that no fuzzed config holds would go untested: add
    it to _EXTENDED (the sweep file's own sections are fuzzed below)."""
    numbers = {(cls, name) for cls in _sections() if cls.__module__ == Section.__module__
               for name, info in cls.model_fields.items() if _holds_numbers(info.annotation)}
    reached = {_field(CONFIGS[name][1], path) for name, path, _ in CASES}
    assert sorted((c.__name__, f) for c, f in numbers - reached) == []


# ---------------------------------------------------------------- sweep files
def _load_sweep(tmp_path, data):
    """Sweep.load of the sweep file ``data``, its base config taken from examples/."""
    path = tmp_path / "sweep.toml"
    path.write_text(tomli_w.dumps({**data, "base": str(EXAMPLES / data["base"])}))
    return Sweep.load(path)


def _sweep_cases(kind):
    """(file name, path, value) of the sweep numbers of one kind: seeds, values, display."""
    return [(name, path, value) for name, data in SWEEPS.items()
            for path, value in _numbers(data) if kind in path]


def _ids(cases):
    return [f"{n}:{'.'.join(map(str, p))}" for n, p, _ in cases]


VALUES = _sweep_cases("values")


def _check_swept(name, path, value, bads, tmp_path):
    """Each of ``bads`` in place of the swept ``value`` is refused naming [[vary]] and
    the config field it sets, as the point's config does."""
    data = SWEEPS[name]
    k = path[1]
    parameter = data["vary"][k]["parameter"]
    _, config = CONFIGS[data["base"]]
    target = _config_path(config, parameter)
    owner, field = _field(config, target)
    where = ".".join(map(str, target))
    for bad in bads:
        with pytest.raises(ConfigError) as err:
            _load_sweep(tmp_path, _replaced(data, path, bad))
        line = _refusal(err, tmp_path / "sweep.toml")
        assert line.startswith(f"  vary.{k} {parameter} = {bad!r}: {where} = {bad!r}: "), \
            line
        assert line.endswith(f"  ({owner.model_fields[field].description})"), line


@pytest.mark.parametrize("name, path, value", VALUES, ids=_ids(VALUES))
def test_a_swept_value_is_a_number(name, path, value, tmp_path):
    """A value of [[vary]] is checked as the config field it sets, in its point."""
    _check_swept(name, path, value, [True, False, str(value)], tmp_path)


def test_a_swept_value_is_finite(tmp_path):
    for name, path, value in VALUES:
        _check_swept(name, path, value, NON_FINITE, tmp_path)


SEEDS = _sweep_cases("seeds")


@pytest.mark.parametrize("name, path, value", SEEDS, ids=_ids(SEEDS))
def test_a_seed_is_finite(name, path, value, tmp_path):
    for bad in NON_FINITE:
        with pytest.raises(ConfigError) as err:
            _load_sweep(tmp_path, _replaced(SWEEPS[name], path, bad))
        line = _refusal(err, tmp_path / "sweep.toml")
        assert line.startswith(f"  seeds.{path[1]} = {bad!r}: "), line


DISPLAY = _sweep_cases("display")


@pytest.mark.parametrize("name, path, value", DISPLAY, ids=_ids(DISPLAY))
def test_a_display_value_may_be_text(name, path, value, tmp_path):
    """Display values label tables and figures: a string is a label too."""
    sweep = _load_sweep(tmp_path, _replaced(SWEEPS[name], path, f"{value} GPa"))
    assert f"{value} GPa" in sweep.spec.vary[path[1]].display


def test_the_sweep_files_own_numbers_refuse_booleans_text_and_non_finite(tmp_path):
    for name, path, value in SEEDS + DISPLAY:
        for bad in NOT_NUMBERS if "display" in path else _bad(value):
            with pytest.raises(ConfigError):
                _load_sweep(tmp_path, _replaced(SWEEPS[name], path, bad))
