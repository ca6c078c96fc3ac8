"""Package hygiene: importing compiles nothing; jit flags live only in _jit.py."""
import pathlib
import subprocess
import sys

SRC = pathlib.Path(__file__).parents[1] / "src" / "graindyn"


def test_import_compiles_nothing_and_is_fast():
    code = ("import time; t = time.perf_counter(); import graindyn; "
            "from graindyn.engines.soft import loop, contacts; from graindyn.core import neighbors; "
            "print(time.perf_counter() - t); "
            "print(sum(len(f.signatures) for f in (loop.run_chunk, contacts.contact_forces, "
            "neighbors.rebuild)))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.split()
    assert float(out[0]) < 3.0
    assert out[1] == "0"


def test_warm_start_loads_the_cache():
    """A second process running the time loop on the named bundles (engines/soft/
    bundles.py) loads every compiled kernel from the disk cache: nothing is compiled."""
    code = ("import graindyn as gd; from graindyn.engines.soft import loop; "
            "st = gd.State.create([[0, 0, 1e-3], [0, 0, 3.5e-3]], [1e-3, 1e-3], 2650.0); "
            "sim = gd.Simulation(st, [gd.Material(restitution=0.5)], "
            "gd.ContactModel('hertz', 'tsuji', 'mindlin'), "
            "walls=[gd.Plane((0, 0, 0), (0, 0, 1))]); sim.run(steps=20); "
            "print(sum(sum(f.stats.cache_misses.values()) for f in (loop.run_chunk, "
            "loop.relist)), sum(sum(f.stats.cache_hits.values()) for f in (loop.run_chunk, "
            "loop.relist)))")
    for _ in range(2):       # the first may fill the cache
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                             check=True).stdout.split()
    assert out == ["0", "2"]


def test_jit_flags_only_in_jit_module():
    for path in SRC.rglob("*.py"):
        if path.name == "_jit.py":
            continue
        text = path.read_text()
        assert "fastmath" not in text, path
        assert "numba.njit" not in text and "@njit" not in text, path


def test_changing_law_or_parameter_does_not_recompile():
    """One compiled loop serves every law and parameter: the law ids and the pair table
    are run-time data (DESIGN.md), so a second model adds no signature."""
    import numpy as np

    import graindyn as gd
    from graindyn.engines.soft import loop

    def run(model, material):
        st = gd.State.create([[0, 0, 1e-3], [0, 0, 3.5e-3]], [1e-3, 1e-3], 2650.0)
        sim = gd.Simulation(st, [material], model, walls=[gd.Plane((0, 0, 0), (0, 0, 1))])
        sim.run(steps=50)
        return np.isfinite(st.positions).all()

    assert run(gd.ContactModel("hertz", "tsuji", "mindlin"), gd.Material(restitution=0.5))
    before = len(loop.run_chunk.signatures)
    assert run(gd.ContactModel("hooke", "linear", "cundall_strack"),
               gd.Material(kn=1e4, kt=3e3, restitution=0.9, friction_sliding=0.3))
    assert run(gd.ContactModel("hertz", "viscoelastic", "coulomb"),
               gd.Material(youngs_modulus=5e7, gamma_n=1e4, friction_sliding=0.2))
    assert len(loop.run_chunk.signatures) == before == 1


def test_readme_quick_tour_runs(capsys):
    """The README's Python quick tour runs as printed (500 grains settle)."""
    import re

    readme = (SRC.parents[1] / "README.md").read_text()
    code = re.search(r"```python\n(.*?)```", readme, re.S).group(1)
    scope = {}
    exec(compile(code, "README.md", "exec"), scope)
    report = scope["report"]
    assert 0.45 < report["packing_fraction"] < 0.7
    assert 3.0 < report["coordination_number"] < 7.0


def test_cache_command_shows_and_clears_old_folders(tmp_path):
    """``graindyn cache`` lists the folders under GRAINDYN_CACHE_DIR; ``cache clear``
    removes those of other sources and keeps the one in use (``--all``: that one too)."""
    import os

    old = tmp_path / "0123456789abcdef-omp"
    old.mkdir()
    (old / "kernel.nbc").write_bytes(b"x" * 2_000_000)
    env = {**os.environ, "GRAINDYN_CACHE_DIR": str(tmp_path)}

    def cli(*args):
        return subprocess.run([sys.executable, "-m", "graindyn", "cache", *args], env=env,
                              capture_output=True, text=True, check=True).stdout

    current = cli().splitlines()
    assert any(old.name in line and "2.0 MB" in line for line in current)
    in_use = next(line.split()[0] for line in current if "(in use" in line)
    (tmp_path / in_use).mkdir(exist_ok=True)
    assert "removed 1 folder(s), 2.0 MB" in cli("clear")
    assert not old.exists() and (tmp_path / in_use).exists()
    cli("clear", "--all")
    assert not any(tmp_path.iterdir())
