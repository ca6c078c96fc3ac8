"""Restart identity: a run continued from Simulation.snapshot() in a fresh Simulation
(restore) is bitwise identical to an uninterrupted run, for every integrator (their
history, e.g. Beeman's previous accelerations or Gear's higher derivatives, travels
in the snapshot), with contacts, tangential spring histories, walls and rotation."""
import numpy as np
import pytest

import graindyn as gd
from graindyn.engines.soft.integrators import NAMES

STEPS = 150


def _box(integrator):
    rng = np.random.default_rng(7)
    radius = 0.005
    grid = np.stack(np.meshgrid(np.arange(3), np.arange(3), np.arange(3)), -1).reshape(-1, 3)
    positions = (grid + 0.5) * 2.05 * radius + rng.uniform(-1e-4, 1e-4, grid.shape)
    state = gd.State.create(positions, np.full(len(grid), radius), 2500.0,
                            velocities=rng.normal(0.0, 0.3, grid.shape))
    state.angular_velocities[:] = rng.normal(0.0, 30.0, grid.shape)
    model = gd.ContactModel("hertz", "viscoelastic", "mindlin")
    walls = gd.box((0, 0, 0), (6.2 * radius,) * 3, open_top=False)
    return gd.Simulation(state, [gd.Material(youngs_modulus=1e7, gamma_n=2e3)], model,
                         walls=walls, integrator=integrator, check_interval=7)


@pytest.mark.parametrize("name", NAMES)
def test_restart_continues_identically(name):
    whole = _box(name)
    whole.run(steps=2 * STEPS)
    first = _box(name)
    first.run(steps=STEPS)
    saved = first.snapshot()
    again = _box(name)
    again.restore(saved)
    again.run(steps=STEPS)
    a, b = whole.snapshot(), again.snapshot()
    assert a.keys() == b.keys()
    assert whole.contacts()[0].size > 0, "the test should exercise contacts"
    for key in a:
        np.testing.assert_array_equal(a[key], b[key], err_msg=key)
    if whole.integrator_state:
        assert any(np.any(v != 0) for v in whole.integrator_state.values())


def test_rewind_puts_the_bed_back_and_lets_the_clock_run_on():
    """rewind of a snapshot taken after STEPS steps, STEPS steps later: the grains,
    contacts and integrator history as in the snapshot, the time and step counter where
    they were; with nothing that depends on time (fixed walls), the next STEPS steps
    repeat the snapshot's own next STEPS to the bit, at the later time."""
    sim = _box("gear3")
    sim.run(steps=STEPS)
    saved = sim.snapshot()
    sim.run(steps=STEPS)
    after = sim.snapshot()
    t, step = sim.time, sim.step
    sim.rewind(saved)
    assert (sim.time, sim.step) == (t, step) and sim.state.time == t
    now = sim.snapshot()
    for key in saved:
        if key not in ("loop/clock", "loop/counters"):
            np.testing.assert_array_equal(now[key], saved[key], err_msg=key)
    sim.run(steps=STEPS)
    assert sim.step == step + STEPS
    again = sim.snapshot()
    for key in after:
        if key not in ("loop/clock", "loop/counters"):
            np.testing.assert_array_equal(again[key], after[key], err_msg=key)


def test_restore_refuses_an_incomplete_snapshot():
    sim = _box("beeman")
    saved = sim.snapshot()
    del saved["integrator/previous_accelerations"]
    with pytest.raises(ValueError, match="previous_accelerations"):
        _box("beeman").restore(saved)


def test_reset_integrator_history_takes_hand_made_velocities():
    """leap_frog carries its velocity in the history: grains stopped by hand keep
    moving unless reset_integrator_history() is called, after which the first step
    starts from rest exactly: a grain in free fall moves by g dt^2/2."""
    for reset in (True, False):
        sim = _box("leap_frog")
        sim.run(steps=20)
        sim.state.velocities[:] = 0.0
        if reset:
            sim.reset_integrator_history()
        weight = sim.state.masses[:, None] * np.array([0.0, 0.0, -9.81])
        free_before = np.all(sim.state.forces == weight, axis=1)
        before = sim.state.positions.copy()
        sim.run(steps=1)
        free = free_before & np.all(sim.state.forces == weight, axis=1)
        assert free.sum() >= 1
        step = (sim.state.positions - before)[free]
        fall = np.array([0.0, 0.0, -0.5 * 9.81 * sim.dt**2])
        assert np.allclose(step, fall, rtol=1e-9, atol=0.0) == reset
