"""The threading layer and the thread count are graindyn's choice (graindyn._threads):
OpenMP where numba's pool loads, TBB refused, one thread for small systems."""
import json
import os
import subprocess
import sys
import textwrap

import numba
import pytest

from graindyn import _jit, _threads

# these tests time the cores: the jobs other tests started in the background end first
pytestmark = pytest.mark.usefixtures("quiet_machine")


def _python(code, **env):
    """Run ``code`` in a fresh interpreter with ``env`` added; returns the process."""
    return subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True,
                          text=True, timeout=900, env={**os.environ, **env})


def _tbb_loads():
    try:
        numba.np.ufunc.parallel._check_tbb_version_compatible()
    except ImportError:
        return False
    return True


def test_layer_is_chosen_before_anything_parallel_and_keys_the_cache():
    assert _threads.layer() in _threads.PREFERENCE
    assert numba.config.THREADING_LAYER == _threads.LAYER
    assert _jit.CACHE_DIR.name.endswith("-" + _threads.LAYER)


def test_automatic_count_is_one_thread_below_the_crossover():
    crossover = _threads.CROSSOVER[_threads.layer()]
    assert _threads.automatic(crossover - 1) == 1
    assert _threads.automatic(crossover) == numba.config.NUMBA_NUM_THREADS
    before = numba.get_num_threads()
    try:
        threads, why = _threads.use(0, 100)
        assert threads == numba.get_num_threads() == 1 and "automatic for 100 grains" in why
        assert _threads.use(1, 10**6) == (1, "as asked")          # an explicit count is obeyed
        with pytest.raises(ValueError, match="at most"):
            _threads.use(numba.config.NUMBA_NUM_THREADS + 1, 100)
    finally:
        numba.set_num_threads(before)


# one process: a few hundred grains settling, timed on 1 and then on 2 threads (best of
# three each); prints the layer, the notice and the ratio
_RATIO = """
    import json, time
    import numpy as np, numba
    import graindyn as gd
    from graindyn import _threads

    def sim():
        rng = np.random.default_rng(5)
        n = 300
        side = 7.5e-3
        pos = np.stack(np.meshgrid(*[np.arange(7) * 1.05e-3 + 0.6e-3] * 2, indexing="ij"), -1)
        pos = pos.reshape(-1, 2)
        layers = -(-n // len(pos))
        pos = np.concatenate([np.column_stack([pos, np.full(len(pos), 0.6e-3 + 1.05e-3 * k)])
                              for k in range(layers)])[:n]
        st = gd.State.create(pos, np.full(n, 0.5e-3), 2650.0,
                             velocities=rng.normal(0, 0.05, (n, 3)))
        mat = gd.Material(density=2650.0, restitution=0.8, friction_sliding=0.5,
                          tangential_damping=1.0)
        return gd.Simulation(st, [mat], gd.ContactModel("hertz", "tsuji", "mindlin"),
                             walls=gd.box((0, 0, 0), (side, side, 0.05)))

    def best(threads):
        numba.set_num_threads(threads)
        walls = []
        for _ in range(3):
            s = sim()
            s.run(steps=200)
            t = time.perf_counter()
            s.run(steps=3000)
            walls.append(time.perf_counter() - t)
        return min(walls)

    one, two = best(1), best(2)
    print(json.dumps({"layer": numba.threading_layer(), "notice": _threads.NOTICE,
                      "one": one, "two": two}))
"""


@pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2, reason="needs two cores")
@pytest.mark.parametrize("asked", ["default", "tbb"])
def test_two_threads_are_not_slower_on_the_layer_graindyn_chooses(asked):
    """With NUMBA_THREADING_LAYER unset (numba's own order puts TBB first when libtbb is
    found) or set to tbb, graindyn runs on OpenMP, and two threads forced on 300 grains
    cost at most 5 times one thread: OpenMP 1.4 times on the 280-grain bed (below the
    crossover, where the automatic count takes one thread; about 2 times when another
    process holds one of the two cores), numba's TBB pool 15-100 times and growing
    (BENCHMARKS.md, "Threading layers")."""
    proc = _python(_RATIO, NUMBA_THREADING_LAYER=asked)
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout.splitlines()[-1])
    assert out["layer"] in _threads.PREFERENCE
    if asked == "tbb":
        assert "NUMBA_THREADING_LAYER=tbb refused" in proc.stderr
        assert "numba issue #10556" in out["notice"]
    assert out["two"] < 5.0 * out["one"], out


@pytest.mark.skipif(not _tbb_loads(), reason="libtbb.so.12 not found (CI installs libtbb12)")
def test_threads_already_started_on_tbb_run_a_simulation_on_one_thread():
    """A host program that started numba's threads on TBB before importing graindyn:
    graindyn says so, runs automatic counts on one thread and refuses more."""
    proc = _python("""
        import numba
        from numba.np.ufunc import parallel
        numba.config.THREADING_LAYER = "tbb"
        parallel._launch_threads()
        import numpy as np, graindyn as gd
        from graindyn import _threads
        assert _threads.layer() == "tbb"
        assert _threads.use(0, 10**6)[0] == 1 and numba.get_num_threads() == 1
        try:
            _threads.use(2, 10**6)
        except ValueError as err:
            print("refused:", err)
        st = gd.State.create([[0, 0, 1e-3]], [5e-4], 2650.0)
        sim = gd.Simulation(st, [gd.Material(density=2650.0)], gd.ContactModel("hertz"),
                            walls=[gd.Plane((0, 0, 0), (0, 0, 1))])
        sim.run(time=0.02)
        print("ran", sim.step)
    """)
    assert proc.returncode == 0, proc.stderr
    assert "already run on tbb" in proc.stderr
    assert "refused: run.threads = 2: the threading layer is tbb" in proc.stdout
    assert "ran " in proc.stdout
