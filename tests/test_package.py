"""Package hygiene: importing compiles nothing; jit flags live only in _jit.py."""
import pathlib
import subprocess
import sys

SRC = pathlib.Path(__file__).parents[1] / "src" / "graindyn"


def test_import_compiles_nothing_and_is_fast():
    code = ("import time; t = time.perf_counter(); import graindyn; "
            "from graindyn.core import loop, contacts, neighbors; "
            "print(time.perf_counter() - t); "
            "print(sum(len(f.signatures) for f in (loop.run_chunk, contacts.pair_forces, "
            "neighbors.rebuild)))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.split()
    assert float(out[0]) < 3.0
    assert out[1] == "0"


def test_jit_flags_only_in_jit_module():
    for path in SRC.rglob("*.py"):
        if path.name == "_jit.py":
            continue
        text = path.read_text()
        assert "fastmath" not in text, path
        assert "numba.njit" not in text and "@njit" not in text, path
