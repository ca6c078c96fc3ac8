"""GPU kernels under the CUDA simulator (issue 6): the device step, built from the CPU's
own per-grain functions, follows the CPU step through contacts, rebuilds of the
neighbour lists, a moving wall and every integrator stage.  Needs numba-cuda (the test
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
    """40 steps of an 8-grain frictional bed: positions, velocities, spins, orientations,
    contact histories and wall forces agree to 1e-10 relative (the issue's parity
    tolerance; under the simulator they are in fact equal) and both runs rebuilt their
    neighbour lists the same number of times."""
    env = dict(os.environ, NUMBA_ENABLE_CUDASIM="1")
    done = subprocess.run([sys.executable, str(SCRIPT), "40", model, integrator], env=env,
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    out = json.loads(done.stdout.strip().splitlines()[-1])
    assert out["contacts"] > 0 and out["rebuilds"][0] == out["rebuilds"][1] > 1
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
