"""GPU kernels under the CUDA simulator (issue 6): the device step, built from the CPU's
own per-grain functions, follows the CPU step through contacts, device rebuilds of the
neighbour lists, a moving wall, every integrator stage, the checks and a checkpoint
moved from one backend to the other.  Needs numba-cuda (the test
extra has it); no GPU is used."""
import importlib.util
import json
import os
import pathlib
import subprocess
import sys

import pytest

pytestmark = pytest.mark.skipif(importlib.util.find_spec("numba_cuda") is None,
                                reason="numba-cuda is not installed")

SCRIPT = pathlib.Path(__file__).with_name("cudasim_parity.py")


@pytest.mark.parametrize("model, integrator", [
    ("hertz,tsuji,mindlin,constant,constant", "velocity_verlet"),
    ("hertz,viscoelastic,oquendo,none,oquendo", "optimized_velocity_verlet"),
])
def test_simulated_gpu_step_follows_the_cpu(model, integrator):
    """40 steps of an 8-grain frictional bed, backend "cpu" against backend "gpu", each
    resumed half way from a checkpoint of its own run on the other backend: positions,
    velocities, spins, orientations, contact histories and wall forces agree to 1e-10
    relative (the issue's parity tolerance; under the simulator they are in fact equal)
    and both runs rebuilt their neighbour lists the same number of times."""
    env = dict(os.environ, NUMBA_ENABLE_CUDASIM="1")
    done = subprocess.run([sys.executable, str(SCRIPT), "40", model, integrator], env=env,
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    out = json.loads(done.stdout.strip().splitlines()[-1])
    assert out["contacts"] > 0 and out["rebuilds"][0] == out["rebuilds"][1] > 1
    assert out["steps"] == [40, 40]
    for name in ("positions", "velocities", "angular_velocities", "orientations"):
        assert out[name] <= 1e-10, name
    assert out["history"] <= 1e-15 and out["wall_force"] <= 1e-12
    cpu, gpu = out["dissipated"]
    for kind in ("normal", "tangential"):
        assert gpu[kind] == pytest.approx(cpu[kind], rel=1e-10)


def test_simulated_gpu_builds_the_cpu_neighbour_lists():
    """300 polydisperse grains, periodic in x and y, walls in z: the device build grows
    the lists past their first capacity and writes the CPU's pair, reverse and wall
    lists, element for element; after every grain moves, the rebuilt lists and the
    carried contact histories again equal the CPU's.  A device prefix sum over 8
    blocks equals numpy's cumsum."""
    env = dict(os.environ, NUMBA_ENABLE_CUDASIM="1")
    script = SCRIPT.with_name("cudasim_lists.py")
    done = subprocess.run([sys.executable, str(script)], env=env, capture_output=True,
                          text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    out = json.loads(done.stdout.strip().splitlines()[-1])
    assert out["pairs"] > 600 and out["walls"] > 0 and out["carried"] > 0
    assert out["capacity"][0] == out["capacity"][1]
    assert all(out["first"]) and all(out["second"]) and out["scan"]


def test_simulated_gpu_stops_where_the_cpu_stops():
    """The compiled stop conditions (largest speed, kinetic/potential energy ratio) end
    the run at the same check on both backends, and grains placed deep inside each
    other raise the same OverlapError before the first step."""
    env = dict(os.environ, NUMBA_ENABLE_CUDASIM="1")
    done = subprocess.run([sys.executable, str(SCRIPT), "checks"], env=env,
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    out = json.loads(done.stdout.strip().splitlines()[-1])
    assert out["cpu"] == out["gpu"]
    first, step, energy, overlap = out["gpu"]
    assert (first, step, energy) == ("condition", 14, "condition")
    assert overlap.startswith("an overlap exceeds")


def test_simulated_gpu_collisions_match_the_cpu_for_every_law_and_integrator():
    """Nine short scenarios (an oblique, spinning grain-grain collision and a grain
    sliding onto a plane) that together use every normal, damping, tangential, rolling
    and twisting law and every integrator, in 3D and 2D: the final state on backend gpu
    equals backend cpu to 1e-10 relative (the issue's single-collision tolerance), and
    so do the restitution of the head-on pair, the dissipated energy and the energy
    total."""
    env = dict(os.environ, NUMBA_ENABLE_CUDASIM="1")
    script = SCRIPT.with_name("cudasim_scenarios.py")
    done = subprocess.run([sys.executable, str(script), "60"], env=env, capture_output=True,
                          text=True, timeout=900)
    assert done.returncode == 0, done.stderr[-3000:]
    lines = [json.loads(line) for line in done.stdout.strip().splitlines()]
    assert len(lines) == 9
    for out in lines:
        name = f"{out['model']} {out['integrator']} {out['dim']}D"
        assert out["contact_chunks"] > 0, name
        assert out["difference"] <= 1e-10, name
        cpu, gpu = out["restitution"]
        assert 0.1 < cpu < 1.0 and gpu == pytest.approx(cpu, rel=1e-10), name
        for key in ("dissipated", "energy"):
            assert out[key][1] == pytest.approx(out[key][0], rel=1e-10), name


TINY = """
[run]
name = "tiny"
seed = 3
gravity = [0.0, 0.0, -8000.0]

[grains]
count = 6
material = "quartz"
diameter = { min = 0.9e-3, max = 1.1e-3 }

[[materials]]
name = "quartz"
restitution = 0.8
tangential_damping = 1.0

[[materials]]
name = "steel"
density = 7800.0
youngs_modulus = 2e9
restitution = 0.8

[contact]
normal = "hertz"
damping = "tsuji"
tangential = "mindlin"

[walls]
material = "steel"
container = { kind = "box", lo = [0, 0, 0], hi = [3e-3, 3e-3, 10e-3] }

[protocol]
max_time = 1e-3

[output]
series_every = 5e-4
"""


def test_cli_run_with_backend_gpu_writes_the_cpu_run(tmp_path):
    """`graindyn run --backend gpu` (simulated) through the whole run driver: six grains
    poured under strong gravity into a box, about 400 steps with contacts; its
    results.json and series.csv equal those of --backend cpu (energies to 1e-10),
    and meta.json records the backend."""
    import numpy as np

    config = tmp_path / "tiny.toml"
    config.write_text(TINY)
    runs = {}
    for backend in ("cpu", "gpu"):
        env = dict(os.environ, NUMBA_ENABLE_CUDASIM="1")
        done = subprocess.run([sys.executable, "-m", "graindyn", "run", str(config), "--out",
                               str(tmp_path / backend), "--backend", backend,
                               "--no-progress"], env=env, capture_output=True, text=True,
                              timeout=600)
        assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
        runs[backend] = tmp_path / backend
    meta = json.loads((runs["gpu"] / "meta.json").read_text())
    assert meta["backend"] == "gpu"
    cpu, gpu = (json.loads((runs[b] / "results.json").read_text()) for b in ("cpu", "gpu"))
    assert cpu["steps"] == gpu["steps"] > 300 and cpu["apparent_weight_ratio"] > 0
    for key in ("packing_fraction", "apparent_weight_ratio", "bed_height_m"):
        assert gpu[key] == pytest.approx(cpu[key], rel=1e-10), key
    a, b = (np.genfromtxt(runs[b] / "series.csv", delimiter=",", skip_header=1)
            for b in ("cpu", "gpu"))
    assert a.shape == b.shape and a.shape[0] >= 3
    assert np.allclose(a, b, rtol=1e-10, atol=0.0)
