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


def _disks():
    """36 disks of 5 mm piled on a floor between two walls, settling with friction."""
    rng = np.random.default_rng(11)
    grid = np.stack(np.meshgrid(np.arange(6), np.arange(6), [0]), -1).reshape(-1, 3)
    positions = (grid + 0.5) * 1.02e-2 + rng.uniform(-1e-4, 1e-4, grid.shape)
    positions[:, 2] = 0.0
    state = gd.State.create(positions, np.full(len(grid), 5e-3), 8.0, dim=2)
    walls = [gd.Plane((0, 0, 0), (1, 0, 0)), gd.Plane((0.062, 0, 0), (-1, 0, 0)),
             gd.Plane((0, 0, 0), (0, 1, 0))]
    return gd.Simulation(state, [gd.Material(density=8.0, kn=4e3, kt=1e3, restitution=0.9,
                                             friction_sliding=0.5)],
                         gd.ContactModel("hooke", "linear", "cundall_strack"), walls=walls,
                         gravity=(0.0, -9.81, 0.0), dt=1e-5)


def test_a_2d_snapshot_with_vector_springs_is_read_as_scalar_springs():
    """A 2D snapshot written when the disks' tangential springs were vectors (no
    "loop/springs" entry): restore turns each elongation into the scalar along
    s = z x n (physics.tangential.tangential_planar_spring_force), so the run goes on
    as if it had been written with scalar springs, to rounding."""
    sim = _disks()
    sim.run(steps=20000)
    saved = sim.snapshot()
    ht = int(sim.model_ids[gd.physics.registry.HISTORY + 2])
    pairs = sim.contacts()
    assert pairs[0].size > 20 and np.count_nonzero(saved["pairs/history"][:, ht]) > 20
    old = {k: v.copy() for k, v in saved.items() if k != "loop/springs"}
    # the vector form: zeta_s s, s = z x n, n from the second grain to the first
    start, partners = saved["pairs/start"], saved["pairs/partners"]
    first = np.repeat(np.arange(sim.state.n), np.diff(start))
    m = int(start[-1])
    n = saved["grains/positions"][first] - saved["grains/positions"][partners[:m]]
    n /= np.linalg.norm(n, axis=1)[:, None]
    zeta = old["pairs/history"][:m, ht].copy()
    old["pairs/history"][:m, ht] = zeta * -n[:, 1]
    old["pairs/history"][:m, ht + 1] = zeta * n[:, 0]
    ids = saved["wall_contacts/ids"][:int(saved["wall_contacts/start"][-1])]
    n = np.array([(1.0, 0.0), (-1.0, 0.0), (0.0, 1.0)])[ids]     # the planes' normals
    zeta = old["wall_contacts/history"][:ids.size, ht].copy()
    assert np.count_nonzero(zeta) > 3
    old["wall_contacts/history"][:ids.size, ht] = zeta * -n[:, 1]
    old["wall_contacts/history"][:ids.size, ht + 1] = zeta * n[:, 0]
    again = _disks()
    again.restore(old)
    got = again.snapshot()
    scale = np.abs(saved["pairs/history"][:, ht]).max()
    np.testing.assert_allclose(got["pairs/history"], saved["pairs/history"], rtol=0,
                               atol=1e-12 * scale)
    np.testing.assert_allclose(got["wall_contacts/history"], saved["wall_contacts/history"],
                               rtol=0, atol=1e-12 * scale)
    assert got["loop/springs"][0] == 1
