"""The soft engine's side of the interface where it speaks of steps and integrators
(the contract in test_contract.py speaks only of time), and the inputs its methods
refuse."""
import numpy as np
import pytest

import graindyn as gd
from graindyn.engines.soft.integrators import NAMES

from .test_contract import DOWN, MASS, R, floor, soft

MASS_WEIGHT = MASS * 9.81

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


def _grain_under_a_piston(force):
    """A damped grain on the floor with a piston of 10 grain masses resting on it,
    pushed down by ``force`` [N] (core.walls, piston motion)."""
    walls = [floor(), gd.Plane((0.0, 0.0, 2 * R), (0.0, 0.0, -1.0), name="piston")]
    sim = soft([[0.0, 0.0, R]], walls=walls, restitution=0.3)
    sim.set_motion("piston", gd.Motion("piston", direction=(0.0, 0.0, -1.0), force=force,
                                       mass=10 * sim.state.masses[0]))
    return sim


def test_a_piston_comes_to_rest_on_the_grain_it_presses():
    """The piston's applied force and the grain's weight end on the floor, the piston
    carrying its force (static equilibrium of the column, to 1e-4), after its fall onto
    the grain and the oscillations damped by the contacts."""
    force = 20 * MASS_WEIGHT
    sim = _grain_under_a_piston(force)
    sim.run(time=0.2)
    walls = sim.walls
    assert walls.normal_force(walls.index("piston")) == pytest.approx(force, rel=1e-4)
    assert walls.normal_force(walls.index("floor")) == pytest.approx(force + MASS_WEIGHT,
                                                                      rel=1e-4)
    assert abs(walls.velocity[walls.index("piston"), 2]) < 1e-6
    assert sim.walls.motion_of("piston").kind == "piston"


def test_a_piston_resumes_to_the_bit():
    """A snapshot taken while the piston oscillates on the grain continues bit for bit."""
    sim = _grain_under_a_piston(20 * MASS_WEIGHT)
    sim.run(time=2e-3)
    saved = sim.snapshot()
    sim.run(time=3e-3)
    again = _grain_under_a_piston(20 * MASS_WEIGHT)
    again.restore(saved)
    again.run(time=3e-3)
    for name, value in sim.snapshot().items():
        np.testing.assert_array_equal(again.snapshot()[name], value, err_msg=name)


def test_a_checkpoint_of_eight_motion_columns_still_resumes():
    """Checkpoints written before the piston kept 8 motion columns per wall (no mass):
    they restore with a zero mass column and continue as the run they came from."""
    motion = gd.Motion("sinusoid", direction=(0, 0, 1), amplitude=1e-5, frequency=40.0)

    def build():
        return soft([[0.0, 0.0, R]], walls=[gd.Plane((0, 0, 0), (0, 0, 1), motion=motion)])

    sim = build()
    sim.run(time=1e-3)
    saved = sim.snapshot()
    saved["walls/motion"] = saved["walls/motion"][:, :8]
    again = build()
    again.restore(saved)
    sim.run(time=1e-3)
    again.run(time=1e-3)
    np.testing.assert_array_equal(again.state.positions, sim.state.positions)
    np.testing.assert_array_equal(again.walls.offset, sim.walls.offset)


def test_skin_is_the_one_the_lists_use():
    """Simulation.skin [m] is the skin given (the resolved config records it)."""
    st = gd.State.create([[0.0, 0.0, 1e-3]], [5e-4], 2650.0)
    sim = gd.Simulation(st, [gd.Material(density=2650.0)], gd.ContactModel("hertz"),
                        skin=1.5e-4)
    assert sim.skin == 1.5e-4
