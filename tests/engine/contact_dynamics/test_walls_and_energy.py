"""The contact dynamics engine with moving walls, a cylinder, a periodic direction, and
its energy budget in a frictional pile."""
import numpy as np
import pytest

import graindyn as gd
from graindyn.analysis.energy import energy_budget
from graindyn.core.walls import Periodic
from graindyn.engines.contact_dynamics.engine import ContactDynamics

R = 1e-3                 # grain radius [m]
DENSITY = 2650.0         # [kg/m^3] (3D), [kg/m^2] (2D)
G = 9.81                 # [m/s^2]

pytestmark = pytest.mark.usefixtures("one_thread")


def rigid(positions, walls, dim=3, gravity=(0.0, 0.0, -G), mu=0.0, restitution=0.1,
          periodic=(), **options):
    state = gd.State.create(np.asarray(positions, float), np.full(len(positions), R),
                            DENSITY, dim=dim)
    material = gd.Material(restitution=restitution, friction_static=mu,
                           friction_sliding=mu)
    return ContactDynamics(state, [material], walls=walls, periodic=periodic,
                           gravity=gravity, **{"dt": 1e-4, "tolerance": 1e-10, **options})


def test_rising_floor_lifts_a_sphere_and_does_its_work():
    """A floor set rising at v = 0.01 m/s under a resting sphere: the sphere rises with
    it and, once the few bounces of the sudden start have died out, rests on it with its
    weight; the start is an impact whose loss is the relative kinetic energy m v^2 / 2,
    and the floor's work is m g dz + m v^2 / 2 + that loss.  (theta = 1: at theta = 1/2
    the sphere's position follows the jump of its velocity half a step late.)"""
    e = rigid([[0.0, 0.0, R]], [gd.Plane((0, 0, 0), (0, 0, 1), name="floor")], theta=1.0)
    e.run(steps=10)
    v = 0.01
    e.set_motion("floor", gd.Motion("velocity", velocity=(0.0, 0.0, v)))
    z0 = e.state.positions[0, 2]
    e.run(time=0.05)
    rise = e.state.positions[0, 2] - z0
    assert rise == pytest.approx(e.walls.offset[0, 2], rel=1e-9)
    assert e.state.velocities[0, 2] == pytest.approx(v, rel=1e-9)
    m = e.state.masses[0]
    assert e.wall_contacts().normal_force.sum() == pytest.approx(m * G, rel=1e-8)
    energies = e.energies()
    assert energies["dissipated_normal"] == pytest.approx(0.5 * m * v**2, rel=1e-6)
    assert energies["wall_work"] == pytest.approx(m * G * rise + m * v**2, rel=1e-9)


def test_sphere_pressed_against_a_cylinder_wall():
    """Gravity along x pushes a sphere against the inside of a cylinder of radius 5 R
    about z: it rests touching it, the wall's force its weight, the normal inward."""
    e = rigid([[4 * R, 0.0, 0.0]], [gd.Cylinder((0, 0, 0), (0, 0, 1), 5 * R)],
              gravity=(G, 0.0, 0.0))
    e.run(steps=200)
    c = e.wall_contacts()
    m = e.state.masses[0]
    assert c.normal_force.tolist() == pytest.approx([m * G], rel=1e-8)
    np.testing.assert_allclose(c.normal[0], [-1.0, 0.0, 0.0], atol=1e-12)
    assert e.state.positions[0, 0] == pytest.approx(4 * R, abs=1e-15)
    assert e.walls.normal_force(0) == pytest.approx(m * G, rel=1e-8)


def test_elastic_collision_across_a_periodic_boundary():
    """Two equal disks on a frictionless floor, periodic in x over 10 R; the moving one
    meets the resting one across the boundary, elastically (e = 1): they exchange
    velocities."""
    walls = [gd.Plane((0, 0, 0), (0, 1, 0), name="floor")]
    e = rigid([[8.5 * R, R], [0.5 * R, R]], walls, dim=2, gravity=(0.0, -G, 0.0),
              restitution=1.0, periodic=[Periodic(0, 0.0, 10 * R)], dt=1e-5)
    e.state.velocities[0, 0] = 0.05
    e.run(time=0.02)
    np.testing.assert_allclose(e.state.velocities[:, 0], [0.0, 0.05], atol=1e-12)


def test_energy_budget_balances_in_a_frictional_pile():
    """Twenty rough, inelastic disks falling into a box: the budget kinetic + rotational
    + gravitational + dissipated (normal + tangential) stays constant to rounding, and
    both dissipations grow.  (A few steps of its impacts need
    more NLGS sweeps than the default 1000: the cap is raised.)"""
    rng = np.random.default_rng(3)
    grid = np.stack(np.meshgrid(np.arange(5), np.arange(4)), -1).reshape(-1, 2)
    positions = (grid + 0.5) * 2.3 * R + rng.uniform(-0.1 * R, 0.1 * R, grid.shape)
    e = rigid(positions, gd.box((0.0, 0.0), (11.5 * R, 30 * R), dim=2), dim=2,
              gravity=(0.0, -G, 0.0), mu=0.5, restitution=0.2, tolerance=1e-4,
              max_iterations=20000)
    e.state.velocities[:, :2] = rng.normal(0.0, 0.05, (len(positions), 2))
    start = energy_budget(e)
    scale = abs(start["gravitational"]) + start["kinetic"]
    totals = []
    e.run(time=0.1, every=[(gd.Periodic(steps=50), lambda x: totals.append(
        energy_budget(x)["total"]))])
    assert np.abs(np.array(totals) - start["total"]).max() < 1e-12 * scale
    end = e.energies()
    assert end["dissipated_normal"] > 0 and end["dissipated_tangential"] > 0


def test_disk_rests_on_a_segment():
    """A disk on a finite segment (2D): at rest on it, its weight on the segment, the
    normal from the segment to the disk."""
    e = rigid([[0.5 * R, R]], [gd.Segment((-5 * R, 0.0), (5 * R, 0.0), name="ledge")],
              dim=2, gravity=(0.0, -G, 0.0))
    e.run(steps=200)
    c = e.wall_contacts()
    m = e.state.masses[0]
    assert c.normal_force.tolist() == pytest.approx([m * G], rel=1e-8)
    np.testing.assert_allclose(c.normal[0], [0.0, 1.0, 0.0], atol=1e-12)
    assert np.abs(e.state.velocities).max() < 1e-12
