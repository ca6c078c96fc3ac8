"""Run by tests/gpu/test_cudasim.py under NUMBA_ENABLE_CUDASIM=1: a small frictional
bed with a piston moving down, run with backend "cpu" and backend "gpu" (the first
half, then a checkpoint resumed on the other backend for the second half), then
compared; prints one JSON line."""
import json
import sys

import numpy as np

import graindyn as gd
from graindyn.engines.soft.simulation import OverlapError
from graindyn.core.walls import Motion


def make(model, integrator, backend):
    rng = np.random.default_rng(4)
    g = (np.arange(2) + 0.5) * 2.1e-3
    pos = np.stack(np.meshgrid(g, g, g), -1).reshape(-1, 3) + rng.normal(scale=5e-5,
                                                                        size=(8, 3))
    state = gd.State.create(pos, rng.uniform(0.95e-3, 1.05e-3, 8), 2650.0)
    state.velocities[:] = rng.normal(scale=0.3, size=(8, 3))
    state.angular_velocities[:] = rng.normal(scale=30.0, size=(8, 3))
    grain = gd.Material(youngs_modulus=1e7, restitution=0.8, friction_sliding=0.5,
                        friction_static=0.6, friction_rolling=0.05, friction_twisting=0.05,
                        gamma_n=5e5, gamma_nt=1e4, slip_threshold=1e-4)
    piston = gd.Plane((0, 0, 4.3e-3), (0, 0, -1),
                      motion=Motion("velocity", velocity=(0.0, 0.0, -0.2)))
    walls = list(gd.box((0, 0, 0), (4.2e-3, 4.2e-3, 8e-3))) + [piston]
    return gd.Simulation(state, [grain], gd.ContactModel(*model), walls=walls, dt=2e-6,
                         skin=2e-5, integrator=integrator, check_interval=7,
                         backend=backend)


def main(steps, model, integrator):
    cpu, gpu = make(model, integrator, "cpu"), make(model, integrator, "gpu")
    half = steps // 2
    cpu.run(steps=half)
    gpu.run(steps=half)
    # swap the backends through checkpoints for the second half
    cpu_state, gpu_state = cpu.snapshot(), gpu.snapshot()
    cpu, gpu = make(model, integrator, "gpu"), make(model, integrator, "cpu")
    cpu.restore(cpu_state)
    gpu.restore(gpu_state)
    cpu.run(steps=steps - half)
    gpu.run(steps=steps - half)
    out = {"contacts": int(len(cpu.contacts()[0])), "rebuilds": [cpu.rebuilds, gpu.rebuilds],
           "dissipated": [cpu.dissipated, gpu.dissipated], "wall_work": [cpu.wall_work,
                                                                         gpu.wall_work],
           "steps": [cpu.step, gpu.step]}
    for name in ("positions", "velocities", "angular_velocities", "orientations"):
        a, b = getattr(cpu.state, name), getattr(gpu.state, name)
        out[name] = float(np.abs(a - b).max() / np.abs(a).max())
    out["history"] = float(np.abs(cpu.pairs.history - gpu.pairs.history).max())
    out["wall_force"] = float(np.abs(cpu.walls.force - gpu.walls.force).max())
    print(json.dumps(out))


def checks():
    """The stop condition and the overlap check of run_chunk on both backends."""
    out = {}
    model = ["hertz", "tsuji", "mindlin"]
    for backend in ("cpu", "gpu"):
        sim = make(model, "velocity_verlet", backend)
        speed = float(np.linalg.norm(sim.state.velocities, axis=1).max())
        first = sim.run(steps=40, until=gd.MaxSpeedBelow(2.0 * speed))
        energy = sim.run(steps=40, until=gd.EnergyRatioBelow(1e30))
        deep = make(model, "velocity_verlet", backend)
        deep.state.positions[1] = deep.state.positions[0] + [1.2e-3, 0.0, 0.0]
        try:
            deep.run(steps=5)
            overlap = "no error"
        except OverlapError as err:
            overlap = str(err)[:40]
        out[backend] = [first, sim.step, energy, overlap]
    # two grains meeting head-on with no wall and no gravity, 400 steps in chunks of 100
    for backend in ("cpu", "gpu"):
        state = gd.State.create(np.array([[0.0, 0.0, 0.0], [2.2e-3, 0.1e-3, 0.0]]),
                                np.full(2, 1e-3), 2650.0,
                                velocities=np.array([[0.5, 0.0, 0.0], [-0.5, 0.0, 0.0]]))
        grain = gd.Material(youngs_modulus=1e7, restitution=0.8, friction_sliding=0.5)
        free = gd.Simulation(state, [grain], gd.ContactModel(*model), gravity=(0, 0, 0),
                             dt=2e-6, skin=2e-5, backend=backend)
        for _ in range(4):
            free.run(steps=100)
        out[f"free-{backend}"] = [sum(free.dissipated.values()), free.rebuilds,
                                  float(free.state.velocities[0, 0])]
        if backend == "gpu":
            out["reads"] = free._device.reads
    print(json.dumps(out))


if __name__ == "__main__":
    if sys.argv[1] == "checks":
        checks()
    else:
        main(int(sys.argv[1]), sys.argv[2].split(","), sys.argv[3])
