"""A tiny deposition config (30 grains, 0.01 s: a few thousand steps) and sweep files
around it, and ``python -m graindyn`` as a subprocess."""
import copy
import signal
import subprocess
import sys

import pytest
import tomli_w

TINY = {
    "run": {"name": "tiny", "seed": 3},
    "grains": {"count": 30, "material": "sand",
               "diameter": {"min": 0.9e-3, "max": 1.1e-3}},
    "materials": [{"name": "sand", "restitution": 0.8, "tangential_damping": 1.0,
                   "friction_sliding": 0.5},
                  {"name": "steel", "density": 7800.0, "youngs_modulus": 2e9,
                   "restitution": 0.8}],
    "contact": {"normal": "hertz", "damping": "tsuji", "tangential": "mindlin"},
    "walls": {"material": "steel",
              "container": {"kind": "box", "lo": [0, 0, 0], "hi": [5e-3, 5e-3, 30e-3]}},
    # threshold: never settles early, so a run lasts max_time
    "protocol": {"max_time": 0.01, "threshold": 1e-30},
    "output": {"series_every": 5e-3, "figures": False, "checkpoint_every_steps": 5000},
}


@pytest.fixture
def tiny():
    """A fresh deep copy of the tiny base config dict."""
    return copy.deepcopy(TINY)


def write_sweep(folder, sweep, base=None, name="sweep.toml"):
    """Write base.toml (default TINY) and the sweep file (base = "base.toml" unless
    given) into ``folder``; returns the sweep file's path."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "base.toml").write_text(tomli_w.dumps(TINY if base is None else base))
    path = folder / name
    path.write_text(tomli_w.dumps({"base": "base.toml", **sweep}))
    return path


def _default_sigint():
    """A shell that starts the tests in the background makes them ignore SIGINT, and
    children inherit that: give the sweep the SIGINT of a terminal."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def cli(*args, **kw):
    """``python -m graindyn ARGS`` as a real subprocess in its own session (so a
    SIGINT to its process group is a terminal's Ctrl-C), stdout and stderr merged."""
    return subprocess.Popen([sys.executable, "-m", "graindyn", *map(str, args)],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            start_new_session=True, preexec_fn=_default_sigint, **kw)
