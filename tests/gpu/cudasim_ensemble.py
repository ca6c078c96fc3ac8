"""Run by tests/gpu/test_cudasim.py under NUMBA_ENABLE_CUDASIM=1: an ensemble of four
different systems advanced by one set of device kernels against each system run
alone on the device; prints one JSON line.

  A  the 8-grain frictional bed of cudasim_parity.py, piston moving down, 30 steps;
  B  18 grains in contact, periodic in x and y (contacts across the period), a floor
     only, another material, time step, gravity and check interval, 30 steps;
  C  the bed of A from another seed, stopped by MaxSpeedBelow at its first check;
  D  two grains deep inside each other: OverlapError before the first step.
"""
import json

import numpy as np

import graindyn as gd
from graindyn.engines.soft.simulation import SimulationError

from cudasim_parity import make as make_bed

MODEL = ("hertz", "tsuji", "mindlin", "constant", "constant")


def make_periodic():
    rng = np.random.default_rng(11)
    g = (np.arange(3) + 0.5) * 2.0e-3
    pos = np.stack(np.meshgrid(g, g, (np.arange(2) + 0.5) * 2.0e-3), -1).reshape(-1, 3)
    pos += rng.normal(scale=4e-5, size=pos.shape)
    state = gd.State.create(pos, rng.uniform(0.9e-3, 1.05e-3, len(pos)), 2500.0)
    state.velocities[:] = rng.normal(scale=0.2, size=pos.shape)
    grain = gd.Material(youngs_modulus=2e7, restitution=0.6, friction_sliding=0.3,
                        friction_static=0.4, friction_rolling=0.02, friction_twisting=0.03)
    return gd.Simulation(state, [grain], gd.ContactModel(*MODEL),
                         walls=[gd.Plane((0, 0, 0), (0, 0, 1))],
                         periodic=[gd.PeriodicBoundary(0, 0.0, 6e-3),
                                   gd.PeriodicBoundary(1, 0.0, 6e-3)],
                         gravity=(0.0, 1.0, -5.0), dt=1.5e-6, skin=3e-5, check_interval=5,
                         backend="gpu")


def members():
    a = make_bed(MODEL, "velocity_verlet", "gpu")
    b = make_periodic()
    c = make_bed(MODEL, "velocity_verlet", "gpu")
    c.state.velocities[:] *= 0.5
    d = make_bed(MODEL, "velocity_verlet", "gpu")
    d.state.positions[1] = d.state.positions[0] + [1.2e-3, 0.0, 0.0]
    speed = float(np.linalg.norm(c.state.velocities, axis=1).max())
    return [a, b, c, d], [None, None, gd.MaxSpeedBelow(2.0 * speed), None]


def outcome(result):
    return type(result).__name__ if isinstance(result, SimulationError) else result


def main():
    alone, until = members()
    solo = []
    for sim, u in zip(alone, until):
        try:
            solo.append(sim.run(steps=30, until=u))
        except SimulationError as err:
            solo.append(err)
    together, until = members()
    joint = gd.Ensemble(together).run(steps=30, until=until)
    equal = []
    for x, y in zip(alone, together):
        a, b = x.snapshot(), y.snapshot()
        equal.append(sorted(k for k in a if not np.array_equal(a[k], b[k])))
    print(json.dumps({"alone": [outcome(r) for r in solo],
                      "ensemble": [outcome(r) for r in joint],
                      "steps": [[x.step for x in alone], [y.step for y in together]],
                      "rebuilds": [[x.rebuilds for x in alone], [y.rebuilds for y in together]],
                      "contacts": [len(x.contacts()[0]) for x in together],
                      "differ": equal}))


if __name__ == "__main__":
    main()
