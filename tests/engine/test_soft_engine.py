"""The soft engine's side of the interface where it speaks of steps and integrators
(the contract in test_contract.py speaks only of time), and the inputs its methods
refuse."""
import numpy as np
import pytest

import graindyn as gd
from graindyn.engines.soft.integrators import NAMES

from .test_contract import DOWN, R, floor, soft

pytestmark = pytest.mark.usefixtures("one_thread")


@pytest.mark.parametrize("integrator", NAMES)
def test_relocated_system_goes_on_as_one_started_in_its_state(integrator):
    """After a relocation the run goes on to the bit as a fresh Simulation started from
    the same grains: the relocated grain's old contact history is gone, its new floor
    contact is in the lists already for the forces evaluated before the first step,
    and the integrator starts afresh (the multi-step schemes from their start-up)."""
    setting = dict(walls=[floor()], restitution=0.5, integrator=integrator)
    sim = soft([[0.0, 0.0, R], [0.0, 0.0, 3 * R]], **setting)
    sim.run(time=0.05)
    sim.relocate([1], [[5 * R, 0.0, 0.99 * R]], [[0.0, 0.0, -0.01]])
    fresh = soft(sim.state.positions.copy(), velocities=sim.state.velocities.copy(),
                 **setting)
    fresh.state.angular_velocities[:] = sim.state.angular_velocities
    for s in (sim, fresh):
        s.run(steps=200)
    for name in ("positions", "velocities", "angular_velocities", "forces"):
        np.testing.assert_array_equal(getattr(sim.state, name), getattr(fresh.state, name),
                                      err_msg=name)


def test_relocate_refuses_what_it_cannot_place():
    sim = soft([[0.0, 0.0, R], [0.0, 0.0, 3 * R]], walls=[floor()])
    with pytest.raises(ValueError, match="distinct grain indices"):
        sim.relocate([1, 1], [[0, 0, R]] * 2, [[0, 0, 0]] * 2)
    with pytest.raises(ValueError, match="distinct grain indices"):
        sim.relocate([2], [[0, 0, R]], [[0, 0, 0]])
    with pytest.raises(ValueError, match="positions must be finite"):
        sim.relocate([1], [[0, 0, np.nan]], [[0, 0, 0]])
    flat = gd.Simulation(gd.State.create([[0.0, R]], [R], 2650.0, dim=2), [gd.Material()],
                         gravity=(0.0, -9.81, 0.0))
    with pytest.raises(ValueError, match="in 2D"):
        flat.relocate([0], [[0.0, R, 1e-3]], [[0.0, 0.0, 0.0]])
    with pytest.raises(ValueError, match="zero z component in 2D"):
        flat.gravity = DOWN


def test_servo_settings_are_required_once_and_kept_after():
    walls = [floor(), gd.Plane((0, 0, 4 * R), (0, 0, -1), name="piston")]
    sim = soft([[0.0, 0.0, R]], walls=walls)
    with pytest.raises(ValueError, match="not a servo yet: give its gain"):
        sim.set_servo("piston", force=1e-3, max_speed=0.01, direction=(0, 0, -1))
    with pytest.raises(ValueError, match="has no area"):
        sim.set_servo("piston", stress=1e3, gain=1.0, max_speed=0.01, direction=(0, 0, -1))
    with pytest.raises(ValueError, match="time_constant"):
        sim.set_servo("piston", force=1e-3, gain=1.0, time_constant=1e-3, stiffness=1e3,
                      max_speed=0.01, direction=(0, 0, -1))
    sim.set_servo("piston", force=1e-3, time_constant=2e-3, stiffness=1e3, max_speed=0.01,
                  direction=(0, 0, -1))
    sim.set_servo("piston", force=2e-3)
    servo = sim.walls.motion_of("piston")
    assert (servo.kind, servo.force, servo.gain, servo.max_speed, servo.direction) == (
        "servo", 2e-3, 0.5, 0.01, (0.0, 0.0, -1.0))


def test_skin_is_the_one_the_lists_use():
    """Simulation.skin [m] is the skin given (the resolved config records it)."""
    st = gd.State.create([[0.0, 0.0, 1e-3]], [5e-4], 2650.0)
    sim = gd.Simulation(st, [gd.Material(density=2650.0)], gd.ContactModel("hertz"),
                        skin=1.5e-4)
    assert sim.skin == 1.5e-4
