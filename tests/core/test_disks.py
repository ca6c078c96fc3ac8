"""Finite disks (core.walls.Disk): distance and normal against hand-computed values, the
rim included, the NumPy twin against the compiled function, a sphere on the disk, at
its rim and beside it, and a disk plate pressing the grain under it but not the one
beside it."""
import math

import numpy as np
import pytest

import graindyn as gd
from graindyn.core.walls import DISK, Disk, Plane, Walls, wall_distance

R = 1e-3
RHO = 2650.0
G = 9.81


def _compiled(walls, k, point):
    d, nx, ny, nz = wall_distance(walls.kind, walls.geometry, walls.offset, k,
                                  *(float(x) for x in point))
    return d, np.array([nx, ny, nz])


# disk centre (1, 2, 3), normal +z, radius 2: point, distance, normal
E = np.array([0.6, 0.8, 0.0])                       # a radial direction
DISK_CASES = [
    ("face above", (1.5, 2.5, 3.4), 0.4, (0.0, 0.0, 1.0)),
    ("face below", (2.0, 1.0, 2.5), 0.5, (0.0, 0.0, -1.0)),
    ("the centre, on the face", (1.0, 2.0, 3.0), 0.0, (0.0, 0.0, 1.0)),
    ("on the axis, far below", (1.0, 2.0, -7.0), 10.0, (0.0, 0.0, -1.0)),
    ("right over the rim", (3.0, 2.0, 3.7), 0.7, (0.0, 0.0, 1.0)),
    ("beyond the rim, above", (3.3, 2.0, 3.4), 0.5, (0.6, 0.0, 0.8)),
    ("beyond the rim, below, slanted",
     tuple(np.array([1.0, 2.0, 3.0]) + 2.5 * E + (0, 0, -1.2)), 1.3,
     tuple((0.5 * E + (0, 0, -1.2)) / 1.3)),
    ("in its plane beyond the rim", (1.0, 5.0, 3.0), 1.0, (0.0, 1.0, 0.0)),
]


def _disks():
    return Walls([Disk((1.0, 2.0, 3.0), (0.0, 0.0, 1.0), 2.0),
                  Disk((0.0, 0.0, 0.0), (0.0, 3.0, 4.0), 1.0, name="tilted")])


@pytest.mark.parametrize("what, point, distance, normal", DISK_CASES,
                         ids=[c[0] for c in DISK_CASES])
def test_distance_to_a_disk(what, point, distance, normal):
    walls = _disks()
    d, n = _compiled(walls, 0, point)
    assert d == pytest.approx(distance, abs=1e-12)
    assert n == pytest.approx(normal, abs=1e-12)
    twin_d, twin_n = walls.distances(np.array([point]), np.array([0]))
    assert twin_d[0] == pytest.approx(d, abs=1e-14)
    assert twin_n[0] == pytest.approx(n, abs=1e-14)


def test_a_tilted_disk_and_a_moved_disk():
    """Tilted disk (normal (0, 0.6, 0.8), radius 1): a point 0.5 over its plane and 2
    from its axis along e = x is sqrt(1 + 0.25) from the rim point e, along
    (e + 0.5 n) / sqrt(1.25); one 0.3 under its face at 0.5 from the centre is 0.3
    away along -n.  Offsetting the wall moves its distances with it."""
    walls = _disks()
    n = np.array([0.0, 0.6, 0.8])
    e = np.array([1.0, 0.0, 0.0])
    d, normal = _compiled(walls, 1, 2 * e + 0.5 * n)
    assert d == pytest.approx(math.sqrt(1.25), abs=1e-12)
    assert normal == pytest.approx((e + 0.5 * n) / math.sqrt(1.25), abs=1e-12)
    d, normal = _compiled(walls, 1, 0.5 * np.array([0.0, 0.8, -0.6]) - 0.3 * n)
    assert d == pytest.approx(0.3, abs=1e-12) and normal == pytest.approx(-n, abs=1e-12)
    shift = np.array([0.3, -0.2, 0.1])
    walls.offset[0] = shift
    for _, point, distance, expected in DISK_CASES:
        d, normal = _compiled(walls, 0, np.asarray(point) + shift)
        assert d == pytest.approx(distance, abs=1e-12)
        assert normal == pytest.approx(expected, abs=1e-12)


def test_numpy_twin_equals_the_compiled_function_for_disks():
    rng = np.random.default_rng(7)
    walls = Walls([Plane((0, 0, 0), (0, 0, 1)), *_disks().walls])
    assert list(walls.kind) == [0, DISK, DISK]
    points = rng.uniform(-4, 5, (300, 3))
    points[::4, 2] = 3.0                              # in the plane of the first disk
    for k in (1, 2):
        twin_d, twin_n = walls.distances(points, np.full(len(points), k))
        for p, td, tn in zip(points, twin_d, twin_n):
            d, n = _compiled(walls, k, p)
            assert td == pytest.approx(d, rel=1e-12, abs=1e-15)
            assert tn == pytest.approx(n, rel=1e-12, abs=1e-15)
            assert np.linalg.norm(n) == pytest.approx(1.0, rel=1e-12)


def test_a_bad_disk_is_refused_and_its_area_and_force_are_its_own():
    with pytest.raises(ValueError, match="radius must be finite and > 0"):
        Disk((0, 0, 0), (0, 0, 1), 0.0)
    with pytest.raises(ValueError, match="disk normal"):
        Walls([Disk((0, 0, 0), (0, 0, 0), 1.0)])
    with pytest.raises(ValueError, match="center must be a finite 3-vector"):
        Walls([Disk((0, 0), (0, 0, 1), 1.0)])
    assert Disk((0, 0, 0), (0, 0, 1), 2.0).area == pytest.approx(4 * math.pi)
    walls = Walls([Disk((0, 0, 0), (0, 0, -1), 2.0, area=3.0)])
    walls.force[0] = (0.4, 0.3, -2.0)
    assert walls.normal_force(0) == pytest.approx(2.0)   # |F . n|, friction left out
    assert walls.stress(0) == pytest.approx(2.0 / 3.0)


# ---------------------------------------------------------------- dynamics (3D spheres)
def _sphere(x, z, walls, **kw):
    st = gd.State.create([[x, 0.0, z]], [R], RHO)
    mat = gd.Material(density=RHO, youngs_modulus=1e8, poisson_ratio=0.3, restitution=0.3)
    return gd.Simulation(st, [mat], gd.ContactModel("hertz", "tsuji"), walls=walls,
                         gravity=(0.0, 0.0, -G), **kw)


def test_a_sphere_rests_on_a_disk_carrying_its_weight():
    sim = _sphere(2 * R, 3 * R, [Disk((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 5 * R)])
    sim.run(time=0.1)
    st = sim.state
    weight = st.masses[0] * G
    assert np.linalg.norm(st.velocities[0]) < 1e-4
    assert 0.98 * R < st.positions[0, 2] < R
    assert st.positions[0, 0] == pytest.approx(2 * R, abs=1e-12)
    assert sim.walls.normal_force(0) == pytest.approx(weight, rel=1e-3)
    assert sim.walls.force[0] == pytest.approx([0.0, 0.0, -weight], rel=1e-3,
                                               abs=1e-9 * weight)


def test_a_sphere_at_the_rim_is_pushed_outwards_and_one_beside_never_touches():
    """Dropped with its centre 0.6 R beyond the rim of a disk of radius 5 R, a sphere
    lands on the rim, which pushes it along the line from the rim to its centre, outwards,
    and it falls past; dropped 1.5 R beyond the rim it falls past untouched."""
    for beyond, touches in ((0.6 * R, True), (1.5 * R, False)):
        sim = _sphere(5 * R + beyond, 2 * R, [Disk((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 5 * R)])
        touched = []
        sim.run(time=0.06, every=[(gd.Periodic(steps=1),
                                   lambda s: touched.append(s.walls.normal_force(0)))])
        st = sim.state
        assert (max(touched) > 0) == touches
        if touches:
            assert st.velocities[0, 0] > 0                   # pushed away from the rim
        else:
            assert st.velocities[0, 0] == 0.0
        assert st.positions[0, 2] < -5 * R                   # and fell past the disk
        assert sim.walls.normal_force(0) == 0.0


def test_a_disk_plate_presses_the_grain_under_it_not_the_one_beside():
    """A disk plate of radius 3 R, a piston pushed down with F = 10 m g, on two spheres
    resting on a floor: the one under it (x = 0) carries F + m g on the floor, the one
    beside it (x = 6 R, 2 R clear of the rim) only its weight m g; the plate carries F."""
    st = gd.State.create([[0.0, 0.0, R], [6 * R, 0.0, R]], [R, R], RHO)
    mat = gd.Material(density=RHO, youngs_modulus=1e8, poisson_ratio=0.3, restitution=0.3)
    m = float(st.masses[0])
    push = 10 * m * G
    plate = Disk((0.0, 0.0, 2.001 * R), (0.0, 0.0, -1.0), 3 * R, name="plate",
                 motion=gd.Motion("piston", direction=(0, 0, -1), force=push, mass=5 * m))
    sim = gd.Simulation(st, [mat], gd.ContactModel("hertz", "tsuji"),
                        walls=[Plane((0, 0, 0), (0, 0, 1), name="floor"), plate],
                        gravity=(0.0, 0.0, -G))
    sim.run(time=0.05)
    assert np.abs(st.velocities).max() < 1e-4
    assert sim.walls.normal_force(1) == pytest.approx(push, rel=1e-3)
    assert sim.walls.force[1] == pytest.approx([0, 0, push], rel=1e-3, abs=1e-9 * push)
    contacts = sim.wall_contacts()
    on_floor = {int(g): f for g, w, f in zip(contacts.grain, contacts.wall,
                                             contacts.normal_force) if w == 0}
    assert on_floor[0] == pytest.approx(push + m * G, rel=1e-3)
    assert on_floor[1] == pytest.approx(m * G, rel=1e-3)
    assert not np.any((contacts.wall == 1) & (contacts.grain == 1))
    assert st.positions[1] == pytest.approx([6 * R, 0.0, st.positions[1, 2]], abs=1e-12)


def test_a_disk_is_drawn_as_a_fan_on_its_plane():
    from graindyn.output.vtk import walls_mesh

    walls = Walls([Disk((1.0, 2.0, 3.0), (0.0, 0.0, 1.0), 2.0)])
    mesh = walls_mesh(walls, np.zeros(3), np.full(3, 5.0), segments=12)
    quads = mesh.cells[0].data
    assert quads.shape == (12, 4) and np.all(quads[:, 0] == 0)
    points = mesh.points
    assert points[0] == pytest.approx((1.0, 2.0, 3.0))
    assert np.all(points[:, 2] == 3.0)
    assert np.hypot(points[1:, 0] - 1.0, points[1:, 1] - 2.0) == pytest.approx(np.full(12, 2.0))


@pytest.mark.parametrize("engine", ["event_driven", "contact_dynamics"])
def test_the_hard_grain_engines_hold_a_grain_on_a_disk_and_let_one_beside_fall(engine):
    """The event-driven and contact-dynamics engines read the disk through the same
    wall_distance: a grain dropped 0.5 R onto its face comes to rest on it (centre at R),
    one dropped 1.5 R beyond its rim falls freely, z = 1.5 R - g t^2 / 2."""
    from graindyn.engines.contact_dynamics.engine import ContactDynamics
    from graindyn.engines.event_driven.engine import EventDriven

    st = gd.State.create(np.array([[0.0, 0.0, 1.5 * R], [6.5 * R, 0.0, 1.5 * R]]),
                         np.full(2, R), RHO)
    make = EventDriven if engine == "event_driven" else ContactDynamics
    sim = make(st, [gd.Material(restitution=0.5)],
               walls=[Disk((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 5 * R, name="plate")],
               gravity=(0.0, 0.0, -G))
    sim.run(time=0.05)
    p = sim.state.positions
    assert p[0] == pytest.approx([0.0, 0.0, R], abs=1e-4 * R)
    assert abs(sim.state.velocities[0, 2]) < 1e-3
    assert p[1, :2] == pytest.approx([6.5 * R, 0.0], abs=1e-12)
    assert p[1, 2] == pytest.approx(1.5 * R - 0.5 * G * 0.05**2, rel=5e-3)
