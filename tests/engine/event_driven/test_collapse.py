"""Inelastic collapse (VALIDATION.md I1, McNamara & Young 1992): three grains on a line,
and the two treatments that prevent it."""
import numpy as np
import pytest

import graindyn as gd
from graindyn.engines.event_driven.engine import EventDriven

RHO = 1e-3          # grain radius [m]: the line's points become spheres this small


def three_on_a_line(r, **options):
    """Points at x = -1, 0, 2 m moving at 1, 0, -1 m/s (VALIDATION.md I1: not symmetric,
    so no triple collision), as spheres of radius RHO whose gaps are the points'
    distances; restitution r, no gravity, smooth grains."""
    x = np.array([-1.0, 0.0, 2.0]) + 2 * RHO * np.arange(3)
    state = gd.State.create(np.c_[x, np.zeros(3), np.zeros(3)], np.full(3, RHO), 1000.0,
                            velocities=[[1.0, 0, 0], [0.0, 0, 0], [-1.0, 0, 0]])
    return EventDriven(state, [gd.Material(restitution=r)], gravity=(0, 0, 0), **options)


@pytest.mark.parametrize("r, collisions", [(0.5, 3), (0.1, 6), (0.075, 17)])
def test_three_grains_collide_a_known_number_of_times_before_they_separate(r, collisions):
    """I1: r = 0.5 -> 3 collisions, 0.1 -> 6, 0.075 -> 17, then they fly apart: the
    outer grains move outwards, and momentum is conserved."""
    engine = three_on_a_line(r)
    engine.run(time=100.0)
    assert engine.collisions == collisions
    v = engine.state.velocities[:, 0]
    assert v[0] <= v[1] <= v[2]
    assert engine.state.masses @ v == pytest.approx(0.0, abs=1e-15)


def test_below_the_critical_restitution_the_cluster_collapses():
    """I1: at r = 0.07 < 7 - 4 sqrt(3) the collisions do not end: the cluster shrinks
    about 4.4 times per collision and its motion stops at a finite time, about 1.765 s
    (VALIDATION.md).  In floating point the sequence ends at round-off: by 1.77 s the
    grains have collided far more often than the 17 times of r = 0.075, their gaps and
    speeds are below 1e-12 of the start's, and no grain is inside another; at 1.76 s
    they still moved."""
    engine = three_on_a_line(0.07)
    engine.run(time=1.76)
    assert np.abs(engine.state.velocities).max() > 1e-5
    engine.run(time=0.01)
    assert engine.collisions > 30
    x = np.sort(engine.state.positions[:, 0])
    gaps = np.diff(x) - 2 * RHO
    assert np.all(gaps > -1e-15) and np.all(gaps < 1e-12)
    assert np.abs(engine.state.velocities).max() < 1e-12


def test_a_grain_bouncing_to_rest_on_a_floor_ends_hopping_by_the_tolerance():
    """Without a collapse treatment a grain bouncing on a floor under gravity would
    make infinitely many bounces in a finite time (their heights fall as r^2 per
    bounce), ending in collisions at one instant; the least rebound (events.py) makes
    it hop by delta = tolerance x radius instead: the run ends, the grain stays within
    2 delta of the floor, its hops take 2 sqrt(2 delta / g), and the energy balance
    holds to 1e-12 of the drop's."""
    from graindyn.analysis.energy import energy_budget

    state = gd.State.create([[0.0, 0.0, 5 * RHO]], [RHO], 1000.0)
    engine = EventDriven(state, [gd.Material(restitution=0.5)],
                         walls=[gd.Plane((0, 0, 0), (0, 0, 1), name="floor")])
    start = energy_budget(engine)
    assert engine.run(time=0.1) == "done"
    hops = engine.wall_collisions
    engine.run(time=0.01)
    delta = 1e-9 * RHO
    assert engine.wall_collisions - hops == pytest.approx(
        0.01 / (2 * np.sqrt(2 * delta / 9.81)), rel=0.01)
    assert RHO <= state.positions[0, 2] <= RHO + 2 * delta
    drop = state.masses[0] * 9.81 * 4 * RHO
    assert abs(energy_budget(engine)["total"] - start["total"]) < 1e-12 * drop


def test_with_the_tc_model_a_bouncing_grain_presses_the_floor_with_its_weight():
    """With the TC model the grain keeps bouncing elastically at a height of order
    g t_c^2, and the mean force of its collisions on the floor over a second is its
    weight (momentum balance: 1 % for a bounce period far below the second)."""
    state = gd.State.create([[0.0, 0.0, 5 * RHO]], [RHO], 1000.0)
    engine = EventDriven(state, [gd.Material(restitution=0.5)],
                         walls=[gd.Plane((0, 0, 0), (0, 0, 1), name="floor")],
                         collapse="tc", contact_duration=1e-4)
    engine.run(time=1.0)
    engine.run(time=1.0)
    weight = state.masses[0] * 9.81
    assert engine.walls.normal_force(0) == pytest.approx(weight, rel=1e-2)
    assert engine.state.positions[0, 2] - RHO < 9.81 * 1e-4**2


@pytest.mark.parametrize("r", [0.07, 0.01])
def test_the_tc_model_prevents_the_collapse(r):
    """With the TC model (elastic collisions within t_c of a grain's last one) the
    collapsing cluster separates after a finite number of collisions."""
    engine = three_on_a_line(r, collapse="tc", contact_duration=1e-3)
    assert engine.run(time=100.0) == "done"
    assert 0 < engine.collisions < 1000
    v = engine.state.velocities[:, 0]
    assert v[0] <= v[1] <= v[2]


def test_a_speed_dependent_restitution_prevents_the_collapse():
    """With e_n tending to 1 below u0 (collapse = 'speed') the cluster separates too."""
    engine = three_on_a_line(0.07, collapse="speed", collapse_speed=0.5)
    assert engine.run(time=100.0) == "done"
    assert 0 < engine.collisions < 1000


def test_hard_grains_deposited_with_the_tc_model_come_to_rest():
    """Thirty grains (e_n = 0.5, rough) dropped into a box with the TC model reach
    E_kin / E_pot <= 1e-6: the bed's last hops are those of least rebound, no grain is
    inside another or below the floor, and the energy balance holds to 1e-9 of the
    potential energy released.  A floor then set moving at once under the bed (a jump
    of its velocity) shakes it: the one-instant cascades of rough grains wedged between
    the floor and a side wall end (a simultaneous collision is smooth under TC), and no
    grain goes through the floor or into another.  So with the speed model, where a
    collision at the very instant of either grain's previous one is smooth; without a
    treatment ("none") the cascade stops the run with a SimulationError."""
    from graindyn.analysis.energy import energy_budget
    from graindyn.protocols.prepare import BoxRegion, random_insertion

    rng = np.random.default_rng(5)
    side = 8 * RHO
    positions, radii = random_insertion(np.full(30, RHO), BoxRegion(
        (0, 0, 0), (side, side, 16 * RHO)), rng)
    state = gd.State.create(positions, radii, 1000.0)
    engine = EventDriven(state, [gd.Material(restitution=0.5)],
                         walls=gd.box((0, 0, 0), (side, side, 40 * RHO)),
                         tangential_restitution=0.0, collapse="tc", contact_duration=3e-5)
    start = energy_budget(engine)
    assert engine.run(time=1.0, until=gd.EnergyRatioBelow(1e-6)) == "condition"
    end = energy_budget(engine)
    released = start["gravitational"] - end["gravitational"]
    assert released > 0
    assert abs(end["total"] - start["total"]) < 1e-9 * released
    assert np.all(state.positions[:, 2] >= RHO * (1 - 1e-6))
    d = np.linalg.norm(state.positions[:, None] - state.positions[None], axis=2)
    np.fill_diagonal(d, np.inf)
    assert d.min() >= 2 * RHO * (1 - 1e-9)
    settled = state.positions.copy(), state.velocities.copy(), \
        state.angular_velocities.copy()
    # a floor set moving at once under the bed of touching grains
    for model in ("tc", "speed", "none"):
        if model != "tc":
            state = gd.State.create(settled[0], radii, 1000.0, velocities=settled[1])
            state.angular_velocities[:] = settled[2]
            engine = EventDriven(state, [gd.Material(restitution=0.5)],
                                 walls=gd.box((0, 0, 0), (side, side, 40 * RHO)),
                                 tangential_restitution=0.0, collapse=model,
                                 collapse_speed=0.01)
        engine.set_motion("zlo", gd.Motion("sinusoid", direction=(0, 0, 1),
                                           amplitude=5e-4, frequency=50.0))
        if model == "none":
            with pytest.raises(gd.SimulationError, match="collapse"):
                engine.run(time=0.02)
            continue
        events = engine.events
        assert engine.run(time=0.02) == "done"
        assert engine.events > events
        assert np.all(state.positions[:, 2] - engine.walls.offset[4, 2] >= RHO * (1 - 1e-6))
        d = np.linalg.norm(state.positions[:, None] - state.positions[None], axis=2)
        np.fill_diagonal(d, np.inf)
        assert d.min() >= 2 * RHO * (1 - 1e-9)
        assert energy_budget(engine)["kinetic"] > 100 * end["kinetic"]      # it moves


def test_tc_restitutions():
    """Under TC a collision within t_c of either grain's last one is elastic (e_n = 1)
    and keeps its tangential restitution; one at the same instant is smooth too
    (e_s = 1); older ones keep both.  The speed model keeps e_s, but for a collision
    at the very instant of either grain's previous one (smooth, e_s = 1)."""
    from graindyn.engines.event_driven.collision import SPEED, TC, restitution_now

    t_c = 1e-4
    assert restitution_now(0.5, 0.0, TC, 1.0, 1.0, 1.0, 0.5 * t_c, t_c) == (1.0, 0.0)
    assert restitution_now(0.5, 0.0, TC, 1.0, 1.0, 0.0, 0.5 * t_c, t_c) == (1.0, 1.0)
    assert restitution_now(0.5, 0.0, TC, 1.0, 1.0, 2 * t_c, 3 * t_c, t_c) == (0.5, 0.0)
    e_n, e_s = restitution_now(0.5, -0.5, SPEED, 0.25, 1.0, 1e-12, 0.5, t_c)
    assert e_n == pytest.approx(1 - 0.5 * 0.25**0.75) and e_s == -0.5
    assert restitution_now(0.5, -0.5, SPEED, 2.0, 1.0, 0.5, 0.0, t_c) == (0.5, 1.0)
