"""A small deposition config shared by the run tests (about 10^4 steps)."""
import copy

import pytest
import tomli_w

from cli_runs import cli

SMALL = {
    "run": {"name": "small", "seed": 3},
    "grains": {"count": 120, "material": "quartz",
               "diameter": {"min": 0.9e-3, "max": 1.1e-3}},
    "materials": [{"name": "quartz", "restitution": 0.8, "tangential_damping": 1.0},
                  {"name": "steel", "density": 7800.0, "youngs_modulus": 2e9,
                   "restitution": 0.8}],
    "contact": {"normal": "hertz", "damping": "tsuji", "tangential": "mindlin"},
    "walls": {"material": "steel",
              "container": {"kind": "box", "lo": [0, 0, 0], "hi": [5e-3, 5e-3, 30e-3]}},
    "protocol": {"max_time": 0.06},
    "output": {"series_every": 2e-3, "vtk_every": 0.01, "vtk_contacts": True},
}


@pytest.fixture
def small_config():
    """A fresh deep copy of the small config dict."""
    return copy.deepcopy(SMALL)


@pytest.fixture
def write_config(tmp_path):
    """write_config(dict, name) -> path of the TOML file in tmp_path."""
    def write(data, name="run.toml"):
        path = tmp_path / name
        path.write_text(tomli_w.dumps(data))
        return path
    return write


@pytest.fixture(scope="session")
def finished(tmp_path_factory):
    """One uninterrupted run of the small config, as a real subprocess."""
    folder = tmp_path_factory.mktemp("finished")
    (folder / "run.toml").write_text(tomli_w.dumps(SMALL))
    proc = cli("run", folder / "run.toml", "--out", folder / "run", "--threads", "2")
    out, _ = proc.communicate(timeout=900)
    assert proc.returncode == 0, out
    return folder / "run"
