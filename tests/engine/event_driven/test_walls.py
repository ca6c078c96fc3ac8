"""Hard grains against walls of every kind (planes, the inside of a cylinder, segments,
moving walls), periodic faces, the exact resume, and what the engine refuses."""
import math

import numpy as np
import pytest

import graindyn as gd
from graindyn.analysis.energy import energy_budget
from graindyn.core.engine import SimulationError
from graindyn.core.walls import Cylinder, Motion, Periodic, Segment
from graindyn.engines.event_driven.engine import EventDriven
from graindyn.protocols.prepare import BoxRegion, CylinderRegion, random_insertion

R = 1e-3


def grains(region, n, dim=3, seed=0, speed=0.1):
    rng = np.random.default_rng(seed)
    positions, radii = random_insertion(np.full(n, R), region, rng, dim)
    state = gd.State.create(positions, radii, 2650.0, dim=dim)
    v = rng.normal(0.0, speed, (n, 3))
    if dim == 2:
        v[:, 2] = 0.0
    state.velocities[:] = v
    return state


def total_energy(engine):
    return energy_budget(engine)["total"]


def test_elastic_grains_in_a_closed_box_keep_their_energy_and_stay_inside():
    """Sixty elastic rough grains (e_s = -1) bouncing in a closed box under gravity for
    many thousand collisions: total energy within 1e-11 relative, every grain inside."""
    state = grains(BoxRegion((0, 0, 0), (12 * R, 12 * R, 12 * R)), 60)
    engine = EventDriven(state, [gd.Material()], walls=gd.box((0, 0, 0), (12 * R,) * 3,
                                                              open_top=False),
                         tangential_restitution=-1.0)
    start = total_energy(engine)
    engine.run(time=0.5)
    assert engine.collisions > 3000 and engine.wall_collisions > 1000
    assert total_energy(engine) == pytest.approx(start, rel=1e-11)
    p = state.positions
    assert np.all(p >= R * (1 - 1e-9)) and np.all(p <= 12 * R - R * (1 - 1e-9))


@pytest.mark.parametrize("gravity", [(0.0, 0.0, -9.81), (3.0, 0.0, -9.0)])
def test_grains_inside_a_cylinder_never_cross_it(gravity):
    """Elastic grains in a closed vertical cylinder, gravity along its axis (a closed
    form) or across it (conservative advancement): energy within 1e-10, every grain
    inside the cylinder and above the floor."""
    radius = 8 * R
    state = grains(CylinderRegion((0.0, 0.0), radius, 0.0, 10 * R), 40, speed=0.2)
    walls = [gd.Plane((0, 0, 0), (0, 0, 1), name="floor"),
             gd.Plane((0, 0, 12 * R), (0, 0, -1), name="lid"),
             Cylinder((0, 0, 0), (0, 0, 1), radius, name="side")]
    engine = EventDriven(state, [gd.Material()], walls=walls, gravity=gravity)
    start = total_energy(engine)
    engine.run(time=0.3)
    assert engine.wall_collisions > 500
    assert total_energy(engine) == pytest.approx(start, rel=1e-10)
    rho = np.linalg.norm(state.positions[:, :2], axis=1)
    assert np.all(rho <= radius - R * (1 - 1e-6))
    assert np.all(state.positions[:, 2] >= R * (1 - 1e-6))


def test_disks_in_a_funnel_of_segments_stay_on_its_side():
    """Elastic disks in a 2D funnel of two segments (conservative advancement, the
    segments' ends included) under a closed box: energy within 1e-10, no disk through
    a segment."""
    width = 20 * R
    state = grains(BoxRegion((2 * R, 8 * R), (width - 2 * R, 20 * R)), 30, dim=2, speed=0.2)
    walls = gd.box((0, 0), (width, 24 * R), open_top=False, dim=2) + [
        Segment((0.0, 10 * R), (0.45 * width, 2 * R), name="left"),
        Segment((width, 10 * R), (0.55 * width, 2 * R), name="right")]
    engine = EventDriven(state, [gd.Material()], walls=walls, gravity=(0.0, -9.81, 0.0))
    start = total_energy(engine)
    engine.run(time=0.3)
    assert engine.wall_collisions > 300
    assert total_energy(engine) == pytest.approx(start, rel=1e-10)
    for k in (len(walls) - 2, len(walls) - 1):
        distance, normal = engine.walls.distances(state.positions, np.full(state.n, k))
        assert np.all(distance >= R * (1 - 1e-6))
        above = normal[:, 1] > 0
        outside = state.positions[:, 0] > 0.55 * width if k == len(walls) - 1 \
            else state.positions[:, 0] < 0.45 * width
        assert np.all(above | ~outside)


def test_a_vibrated_bed_balances_its_energy_with_the_work_of_the_floor():
    """Inelastic grains (e_n = 0.9, rough) on a floor vibrating at 50 Hz, 0.5 mm (the
    driven granular gas): the floor's work is positive, and kinetic + rotational +
    gravitational + dissipated - wall work stays constant to 1e-9 of the work."""
    side = 10 * R
    state = grains(BoxRegion((0, 0, R), (side, side, 10 * R)), 40)
    walls = gd.box((0, 0, 0), (side, side, 30 * R))
    engine = EventDriven(state, [gd.Material(restitution=0.9)], walls=walls,
                         tangential_restitution=0.2, collapse="tc", contact_duration=1e-5)
    engine.set_motion("zlo", Motion("sinusoid", direction=(0, 0, 1), amplitude=5e-4,
                                    frequency=50.0))
    start = energy_budget(engine)
    engine.run(time=0.4)
    end = energy_budget(engine)
    work = end["wall_work"]
    assert work > 0 and end["dissipated_normal"] > 0 and end["dissipated_tangential"] > 0
    assert abs(end["total"] - start["total"]) < 1e-9 * work
    floor = engine.walls.offset[engine.walls.index("zlo"), 2]
    assert floor == pytest.approx(5e-4 * math.sin(2 * math.pi * 50 * engine.time), abs=1e-12)
    assert np.all(state.positions[:, 2] - floor >= R * (1 - 1e-6))


def test_a_wall_at_constant_velocity_does_the_work_it_does():
    """A lid moving down at constant speed into an elastic gas: the energy gained is the
    lid's work (balance to 1e-10 of it), and no grain is above the lid."""
    side = 10 * R
    state = grains(BoxRegion((0, 0, 0), (side, side, 10 * R)), 40, speed=0.05)
    walls = gd.box((0, 0, 0), (side, side, 12 * R)) + [
        gd.Plane((0, 0, 12 * R), (0, 0, -1), name="lid")]
    engine = EventDriven(state, [gd.Material()], walls=walls, gravity=(0, 0, 0))
    engine.set_motion("lid", Motion("velocity", velocity=(0, 0, -0.01)))
    start = energy_budget(engine)
    engine.run(time=0.3)
    end = energy_budget(engine)
    assert end["wall_work"] > 0
    assert abs(end["total"] - start["total"]) < 1e-10 * end["wall_work"]
    lid = 12 * R - 0.01 * engine.time
    assert engine.walls.offset[-1, 2] == pytest.approx(-0.01 * engine.time, rel=1e-12)
    assert np.all(state.positions[:, 2] <= lid - R * (1 - 1e-6))


def test_grains_cross_periodic_faces_and_collide_across_them():
    """Along a periodic x a grain leaves through one face and comes in through the
    other, its coordinate kept in the period; two grains approaching across the face
    collide there, elastic equal masses exchanging their velocities."""
    length = 10 * R
    state = gd.State.create([[9.5 * R, 0, 0], [1.0 * R, 0, 0]], [R / 2, R / 2], 2650.0,
                            velocities=[[0.1, 0, 0], [-0.1, 0, 0]])
    engine = EventDriven(state, [gd.Material()], periodic=[Periodic(0, 0.0, length)],
                         gravity=(0, 0, 0))
    # they close the gap of 0.5 R across the face in 2.5 ms
    engine.run(time=4e-3)
    assert engine.collisions == 1
    np.testing.assert_allclose(state.velocities[:, 0], [-0.1, 0.1], rtol=1e-12)
    engine.run(time=0.2)
    assert np.all((state.positions[:, 0] >= 0) & (state.positions[:, 0] < length))


def test_a_snapshot_resumes_the_run_to_the_bit():
    """Run, snapshot, run on; restore the snapshot into a new engine built from the same
    inputs and run as long: every array ends the same to the bit (rough, inelastic
    grains in a box with a vibrating floor and the TC model)."""
    def build():
        state = grains(BoxRegion((0, 0, R), (10 * R, 10 * R, 10 * R)), 30, seed=4)
        engine = EventDriven(state, [gd.Material(restitution=0.8)],
                             walls=gd.box((0, 0, 0), (10 * R, 10 * R, 30 * R)),
                             tangential_restitution=-0.5, collapse="tc",
                             contact_duration=1e-5)
        engine.set_motion("zlo", Motion("sinusoid", direction=(0, 0, 1), amplitude=2e-4,
                                        frequency=60.0))
        return engine

    engine = build()
    engine.run(time=0.05)
    saved = engine.snapshot()
    engine.run(time=0.05)
    first = engine.snapshot()
    other = build()
    other.restore(saved)
    assert other.time == saved["loop/clock"][0]
    other.run(time=0.05)
    second = other.snapshot()
    assert first.keys() == second.keys()
    for name in first:
        np.testing.assert_array_equal(first[name], second[name], err_msg=name)
    assert engine.collisions > 100


def test_what_hard_grains_cannot_do_is_refused_with_a_reason():
    """Servo and piston walls need lasting contact forces: refused at construction, by
    set_motion and by set_servo; grains that start overlapping stop the first run."""
    state = gd.State.create([[0, 0, R], [0, 0, 3 * R]], [R, R], 2650.0)
    servo = Motion("servo", direction=(0, 0, -1), force=1.0, gain=1e-3, max_speed=0.1)
    lid = gd.Plane((0, 0, 5 * R), (0, 0, -1), name="lid", motion=servo)
    with pytest.raises(ValueError, match="servo and piston walls"):
        EventDriven(state, [gd.Material()], walls=[lid])
    engine = EventDriven(state, [gd.Material()], walls=[gd.Plane((0, 0, 0), (0, 0, 1))])
    with pytest.raises(ValueError, match="lasting contacts"):
        engine.set_servo(0, force=1.0, gain=1e-3, max_speed=0.1, direction=(0, 0, 1))
    with pytest.raises(ValueError, match="servo and piston walls"):
        engine.set_motion(0, Motion("piston", direction=(0, 0, 1), mass=1.0))
    inside = gd.State.create([[0, 0, R], [0, 0, 2.5 * R]], [R, R], 2650.0)
    engine = EventDriven(inside, [gd.Material()], walls=[gd.Plane((0, 0, 0), (0, 0, 1))])
    with pytest.raises(SimulationError, match="grains 0 and 1 overlap by 0.0005 m"):
        engine.run(time=0.01)
    with pytest.raises(ValueError, match="tangential_restitution must be in"):
        EventDriven(state, [gd.Material()], tangential_restitution=1.5)
    with pytest.raises(ValueError, match="'tc' needs contact_duration"):
        EventDriven(state, [gd.Material()], collapse="tc")
