"""GPU kernels under the CUDA simulator: the device step, built from the CPU's
own per-grain functions, follows the CPU step through contacts, device rebuilds of the
neighbour lists, a moving wall, every integrator stage, the checks and a checkpoint
moved from one backend to the other; ensembles, the run and sweep commands, and the
silo protocol swept as one ensemble.  Needs numba-cuda (the test extra has it); no GPU
is used.  The simulator is slow and single-threaded: every job of this module starts
at once, in its own process (start_early), so that they share the machine's cores;
each test then waits for its own.  With GRAINDYN_GPU=device the same jobs run on the
machine's GPU instead of the simulator, and the same checks judge them
(benchmarks/gpu_session.py)."""
import atexit
import importlib.util
import json
import os
import pathlib
import shutil
import subprocess
import sys
import tempfile

import pytest

pytestmark = pytest.mark.skipif(importlib.util.find_spec("numba_cuda") is None,
                                reason="numba-cuda is not installed")

SCRIPT = pathlib.Path(__file__).with_name("cudasim_parity.py")
PARITY = [("hertz,tsuji,mindlin,constant,constant", "velocity_verlet"),
          ("hertz,viscoelastic,oquendo,none,oquendo", "optimized_velocity_verlet")]


def _jobs(folder):
    """Every simulator job of this module: name -> command line."""
    config = folder / "tiny.toml"
    config.write_text(TINY)
    jobs = {f"parity-{integrator}": [str(SCRIPT), "40", model, integrator]
            for model, integrator in PARITY}
    jobs["checks"] = [str(SCRIPT), "checks"]
    jobs["lists"] = [str(SCRIPT.with_name("cudasim_lists.py"))]
    jobs["scenarios"] = [str(SCRIPT.with_name("cudasim_scenarios.py")), "60"]
    jobs["ensemble"] = [str(SCRIPT.with_name("cudasim_ensemble.py"))]
    jobs["silo"] = [str(SCRIPT.with_name("cudasim_silo.py")), str(folder / "silo")]
    short = TINY.replace("max_time = 1e-3", "max_time = 4e-4")
    for backend in ("cpu", "gpu"):
        where = folder / f"sweep-{backend}"
        where.mkdir()
        (where / "base.toml").write_text(short.replace("seed = 3\n",
                                                       f'seed = 3\nbackend = "{backend}"\n'))
        (where / "sweep.toml").write_text(SWEEP)
        jobs[f"sweep-{backend}"] = ["-m", "graindyn", "sweep", str(where / "sweep.toml"),
                                    "--out", str(where / "out"), "--workers", "1"]
    for backend in ("cpu", "gpu"):
        jobs[f"run-{backend}"] = ["-m", "graindyn", "run", str(config), "--out",
                                  str(folder / backend), "--backend", backend,
                                  "--no-progress"]
    return jobs


_STARTED = {}


def start_early():
    """Start every simulator job, each in its own process at the lowest priority, its
    output into files (tests/conftest.py calls this once collection is done and runs
    this module's tests last: the jobs then use the core the single-threaded suite
    leaves idle).  Nothing without numba-cuda."""
    if _STARTED or importlib.util.find_spec("numba_cuda") is None:
        return
    folder = pathlib.Path(tempfile.mkdtemp(prefix="cudasim-"))
    env = dict(os.environ)
    if os.environ.get("GRAINDYN_GPU") != "device":
        env["NUMBA_ENABLE_CUDASIM"] = "1"
    procs = {}
    for name, args in _jobs(folder).items():
        with open(folder / f"{name}.out", "w") as out, open(folder / f"{name}.err", "w") as err:
            procs[name] = subprocess.Popen([sys.executable, *args], env=env, text=True,
                                           stdout=out, stderr=err,
                                           preexec_fn=lambda: os.nice(19))
    _STARTED.update(folder=folder, procs=procs)
    atexit.register(_stop)


def wait_early():
    """Wait for every started job to end (tests/conftest.py quiet_machine)."""
    for proc in _STARTED.get("procs", {}).values():
        proc.wait(timeout=1200)


def _stop():
    """Kill the jobs still running and remove their folder (at the module's end, or at
    exit when a run stops before it)."""
    for proc in _STARTED.get("procs", {}).values():
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    if "folder" in _STARTED:
        shutil.rmtree(_STARTED["folder"], ignore_errors=True)


@pytest.fixture(scope="module")
def simulated():
    """The started jobs; ``simulated(name)`` waits for one and returns its stdout."""
    start_early()
    folder, procs = _STARTED["folder"], _STARTED["procs"]

    def wait(name):
        procs[name].wait(timeout=1200)
        out = (folder / f"{name}.out").read_text()
        err = (folder / f"{name}.err").read_text()
        assert procs[name].returncode == 0, out[-2000:] + err[-3000:]
        return out

    wait.folder = folder
    yield wait
    _stop()


@pytest.mark.parametrize("model, integrator", PARITY)
def test_simulated_gpu_step_follows_the_cpu(simulated, model, integrator):
    """40 steps of an 8-grain frictional bed, backend "cpu" against backend "gpu", each
    resumed half way from a checkpoint of its own run on the other backend: positions,
    velocities, spins, orientations, contact histories and wall forces agree to 1e-10
    relative (the issue's parity tolerance; under the simulator they are in fact equal)
    and both runs rebuilt their neighbour lists the same number of times."""
    done = simulated(f"parity-{integrator}")
    out = json.loads(done.strip().splitlines()[-1])
    assert out["contacts"] > 0 and out["rebuilds"][0] == out["rebuilds"][1] > 1
    assert out["steps"] == [40, 40]
    for name in ("positions", "velocities", "angular_velocities", "orientations"):
        assert out[name] <= 1e-10, name
    assert out["history"] <= 1e-15 and out["wall_force"] <= 1e-12
    cpu, gpu = out["dissipated"]
    for kind in ("normal", "tangential"):
        assert gpu[kind] == pytest.approx(cpu[kind], rel=1e-10)


def test_simulated_gpu_builds_the_cpu_neighbour_lists(simulated):
    """300 polydisperse grains, periodic in x and y, walls in z: the device build grows
    the lists past their first capacity and writes the CPU's pair, reverse and wall
    lists, element for element; after every grain moves, the rebuilt lists and the
    carried contact histories again equal the CPU's.  A device prefix sum over 8
    blocks equals numpy's cumsum."""
    out = json.loads(simulated("lists").strip().splitlines()[-1])
    assert out["pairs"] > 600 and out["walls"] > 0 and out["carried"] > 0
    assert out["capacity"][0] == out["capacity"][1]
    assert all(out["first"]) and all(out["second"]) and out["scan"]


def test_simulated_gpu_stops_where_the_cpu_stops(simulated):
    """The compiled stop conditions (largest speed, kinetic/potential energy ratio) end
    the run at the same check on both backends, and grains placed deep inside each
    other raise the same OverlapError before the first step."""
    out = json.loads(simulated("checks").strip().splitlines()[-1])
    assert out["cpu"] == out["gpu"]
    first, step, energy, overlap = out["gpu"]
    assert (first, step, energy) == ("condition", 14, "condition")
    assert overlap.startswith("an overlap exceeds")


def test_simulated_gpu_steps_without_reading_back_each_step(simulated):
    """Two grains meet head-on with no wall (400 steps, 4 chunks): the device decides
    each step and the host reads the run table about once per list rebuild, never once
    per step; the energy dissipated in the collision (no wall: the wall totals have no
    column) and the rebound equal the CPU's.  (The rebuilds may fall on other steps:
    the CPU bounds the displacement after its fused drift, the GPU before its drift.)"""
    out = json.loads(simulated("checks").strip().splitlines()[-1])
    cpu, gpu = out["free-cpu"], out["free-gpu"]
    assert cpu[0] > 0.0 and gpu[0] == pytest.approx(cpu[0], rel=1e-10)
    assert min(cpu[1], gpu[1]) >= 4 and cpu[2] < 0.0 and gpu[2] == pytest.approx(cpu[2],
                                                                             rel=1e-10)
    # one read per rebuild and per chunk end, plus the batches the collision cut short
    # (its changes of pace are not foreseen); reading each step would be over 400
    assert out["reads"] < 2 * gpu[1] + 4


def test_simulated_gpu_collisions_match_the_cpu_for_every_law_and_integrator(simulated):
    """Nine short scenarios (an oblique, spinning grain-grain collision and a grain
    sliding onto a plane) that together use every normal, damping, tangential, rolling
    and twisting law and every integrator, in 3D and 2D: the final state on backend gpu
    equals backend cpu to 1e-10 relative (the issue's single-collision tolerance), and
    so do the restitution of the head-on pair, the dissipated energy and the energy
    total."""
    lines = [json.loads(line) for line in simulated("scenarios").strip().splitlines()]
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


def test_cli_run_with_backend_gpu_writes_the_cpu_run(simulated):
    """`graindyn run --backend gpu` (simulated) through the whole run driver: six grains
    poured under strong gravity into a box, about 400 steps with contacts; its
    results.json and series.csv equal those of --backend cpu, and meta.json records the
    backend.  Each value of the series is held to 1e-10 of the largest value of its
    unit in the run (energies against the largest energy, forces against the largest
    force): the two backends round differently (compiled kernels against the
    simulator's Python arithmetic, each with this machine's vector math), a few ulps of
    a position that the contact stiffness turns into a larger relative change of a
    small term, such as a contact just closing."""
    import numpy as np

    runs = {}
    for backend in ("cpu", "gpu"):
        simulated(f"run-{backend}")
        runs[backend] = simulated.folder / backend
    meta = json.loads((runs["gpu"] / "meta.json").read_text())
    assert meta["backend"] == "gpu"
    cpu, gpu = (json.loads((runs[b] / "results.json").read_text()) for b in ("cpu", "gpu"))
    assert cpu["steps"] == gpu["steps"] > 300 and cpu["apparent_weight_ratio"] > 0
    for key in ("packing_fraction", "apparent_weight_ratio", "bed_height_m"):
        assert gpu[key] == pytest.approx(cpu[key], rel=1e-10), key
    a, b = (np.genfromtxt(runs[b] / "series.csv", delimiter=",", skip_header=1)
            for b in ("cpu", "gpu"))
    assert a.shape == b.shape and a.shape[0] >= 3
    names = (runs["cpu"] / "series.csv").read_text().splitlines()[0].split(",")
    units = [name.rsplit("[", 1)[-1] for name in names]
    scale = np.array([np.abs(a[:, [k for k, v in enumerate(units) if v == u]]).max()
                      for u in units])
    off = np.abs(a - b) / np.where(scale > 0, scale, 1.0)
    assert off.max() <= 1e-10, dict(zip(names, off.max(axis=0)))


def test_simulated_ensemble_member_equals_the_system_alone(simulated):
    """Four different systems (two walled beds, one stopped early by its condition, one
    failing with an overlap before its first step, and a periodic bed with another
    material, time step, gravity and check interval) advanced as one ensemble: each
    ends with the outcome, step count, rebuild count and every array of its snapshot
    equal to the same system run alone."""
    out = json.loads(simulated("ensemble").strip().splitlines()[-1])
    assert out["alone"] == out["ensemble"] == ["done", "done", "condition", "OverlapError"]
    assert out["steps"][0] == out["steps"][1] == [30, 30, 7, 0]
    assert out["rebuilds"][0] == out["rebuilds"][1]
    assert min(out["rebuilds"][0][:3]) >= 1 and min(out["contacts"][:2]) > 0
    assert out["differ"] == [[], [], [], []]


SWEEP = """
base = "base.toml"
seeds = [3]

[[vary]]
parameter = "materials.quartz.restitution"
values = [0.6]
"""


def test_sweep_with_backend_gpu_runs_its_points_as_one_ensemble(simulated):
    """`graindyn sweep` on a base config with backend gpu (simulated): its two runs go
    through one GPU ensemble (each run's protocol, outputs and figures in its own
    thread, the chunks launched together) and give the results of the same sweep on
    the CPU (to 1e-10); the two runs differ from each other."""
    import numpy as np

    log = simulated("sweep-gpu")
    simulated("sweep-cpu")
    assert "as one GPU ensemble" in log and "rounds of chunks" in log
    results = {}
    for backend in ("cpu", "gpu"):
        out = simulated.folder / f"sweep-{backend}" / "out"
        assert not list(out.glob("*/*/error.txt"))
        results[backend] = {p.parent.parent.name: json.loads(p.read_text())
                            for p in out.glob("*/seed-3/results.json")}
    assert sorted(results["gpu"]) == sorted(results["cpu"]) == ["reference",
                                                                 "restitution=0.6"]
    for name, cpu in results["cpu"].items():
        gpu = results["gpu"][name]
        assert gpu["steps"] == cpu["steps"] > 100
        for key in ("packing_fraction", "apparent_weight_ratio", "bed_height_m"):
            assert gpu[key] == pytest.approx(cpu[key], rel=1e-10), (name, key)
    a, b = results["gpu"]["reference"], results["gpu"]["restitution=0.6"]
    assert not np.isclose(a["energy_J"]["dissipated_normal"],
                          b["energy_J"]["dissipated_normal"], rtol=1e-3)


def test_simulated_silo_follows_the_cpu_through_reinjection_jam_and_tap(simulated):
    """Two tiny silos of examples/silo.toml (cudasim_silo.py: 16 disks, 144 steps each)
    run with backend gpu as one ensemble, then each on backend cpu: the flowing one
    (the example's hole) re-injects the disks that left above the packing
    (Engine.relocate), the other lets no disk out, is found jammed and is tapped
    (every wall a sinusoid for half a period, then put back).  Each ends with its
    positions, velocities, spins, wall offsets and wall forces equal to the CPU's to
    1e-10 relative, and the same steps, exits, avalanche records and end time."""
    out = json.loads(simulated("silo").strip().splitlines()[-1])
    flowing, jammed = out["runs"]["reference/seed-1"], out["runs"]["hole=0.00491/seed-1"]
    for run in (flowing, jammed):
        assert run["steps"][0] == run["steps"][1] > 100
        for key in ("exited", "avalanches", "unfinished", "time_s"):
            assert run[key][0] == run[key][1], key
        for name, difference in run["differ"].items():
            assert difference <= 1e-10, name
    assert flowing["exited"][0] > 0 and not flowing["avalanches"][0]
    (jam,), tap = jammed["avalanches"][0], jammed["unfinished"][0]
    assert jam["first"] and jam["size"] == 0 and jammed["exited"][0] == 0
    # the tap started at the jam and ran its half period (1000 Hz) to the end
    assert not tap["first"] and tap["start_s"] == jam["end_s"]
    assert tap["duration_s"] >= 0.5e-3


def test_sweep_with_backend_gpu_runs_its_silos_as_one_ensemble(simulated):
    """`sweep.run` of the two tiny silos (cudasim_silo.py) with backend gpu: both runs
    go through one GPU ensemble of two members, finish, and the silo's sweep summary
    is written."""
    out = json.loads(simulated("silo").strip().splitlines()[-1])
    assert 2 in out["ensembles"] and max(out["ensembles"]) == 2
    log = "\n".join(out["log"])
    assert "running 2 run(s) with backend gpu together, as one GPU ensemble" in log
    assert "rounds of chunks" in log and "2 of 2 runs finished" in log
    assert out["exit_code"] == 0
    assert {"silo_sweep.md", "silo_sweep.json", "summary.csv"} <= set(out["summary"])
