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


def _piston(z, mass, force=0.0, **motion):
    return gd.Plane((0.0, 0.0, z), (0.0, 0.0, -1.0), name="piston", area=4 * R * R,
                    motion=gd.Motion("piston", direction=(0.0, 0.0, -1.0), force=force,
                                     mass=mass, **motion))


def test_free_piston_falls_by_newtons_law():
    """A piston of mass M pushed by F with nothing in front of it moves with the
    semi-implicit step of core/walls.py: s_n = n dt F/M, x_n = dt^2 F/M n(n+1)/2."""
    M, F, dt, n = 0.05, 2.0, 1e-4, 300
    e = rigid([[0.0, 0.0, R]], [gd.Plane((0, 0, 0), (0, 0, 1)), _piston(50 * R, M, F)],
              gravity=(0.0, 0.0, 0.0), dt=dt)
    e.run(steps=n)
    assert e.walls.offset[1, 2] == pytest.approx(-dt**2 * F / M * n * (n + 1) / 2,
                                                 rel=1e-12)
    assert e.walls.velocity[1, 2] == pytest.approx(-n * dt * F / M, rel=1e-12)


@pytest.mark.parametrize("ratio", [0.5, 1.0, 4.0])
def test_piston_collides_elastically_with_a_free_sphere(ratio):
    """A piston of mass M = ratio m at speed s on a free sphere of mass m (no gravity,
    no applied force, e = 1): the 1D elastic collision of two bodies, sphere at
    2 M s/(M + m), piston at (M - m) s/(M + m); the energy of both is kept."""
    s = 0.05
    e = rigid([[0.0, 0.0, 5 * R]], [_piston(6.5 * R, 1.0)], gravity=(0.0, 0.0, 0.0),
              restitution=1.0, theta=1.0)
    m = e.state.masses[0]
    M = ratio * m
    e.set_motion("piston", gd.Motion("piston", direction=(0.0, 0.0, -1.0), mass=M))
    e.walls.velocity[0] = (0.0, 0.0, -s)
    e.run(steps=200)
    assert e.state.velocities[0, 2] == pytest.approx(-2 * M * s / (M + m), rel=1e-9)
    assert e.walls.velocity[0, 2] == pytest.approx(-(M - m) * s / (M + m), abs=1e-9 * s)
    kinetic = 0.5 * m * e.state.velocities[0, 2] ** 2 + 0.5 * M * e.walls.velocity[0, 2] ** 2
    assert kinetic == pytest.approx(0.5 * M * s**2, rel=1e-9)


def test_massive_piston_rests_on_a_column():
    """A piston of mass M with an applied force F dropped on a column of 4 spheres on a
    floor under gravity: once at rest, the piston's contact carries F (its own weight is
    in F, core/walls.py), the floor F plus the column's weight, each contact between
    spheres F plus the weight above it, and nothing interpenetrates.  (M is ten grain
    masses: the Gauss-Seidel sweeps converge the slower the heavier the piston.)"""
    M, F = 1e-4, 2e-3
    z = [R + 2 * R * k for k in range(4)]
    e = rigid([[0.0, 0.0, h] for h in z],
              [gd.Plane((0, 0, 0), (0, 0, 1), name="floor"), _piston(8.2 * R, M, F)],
              theta=1.0, tolerance=1e-7, max_iterations=5000)
    e.run(time=0.2)
    m = e.state.masses[0]
    assert abs(e.walls.velocity[1, 2]) < 1e-9
    assert e.walls.normal_force(1) == pytest.approx(F, rel=1e-6)
    assert e.walls.normal_force(0) == pytest.approx(F + 4 * m * G, rel=1e-6)
    c = e.contacts()
    above = np.maximum(e.state.positions[c.i, 2], e.state.positions[c.j, 2])
    expected = F + m * G * np.array([sum(h >= a - 1e-9 for h in e.state.positions[:, 2])
                                     for a in above])
    np.testing.assert_allclose(np.sort(c.normal_force), np.sort(expected), rtol=1e-6)
    heights = np.sort(e.state.positions[:, 2])
    assert heights[0] >= R * (1 - 1e-9)
    assert np.diff(heights).min() >= 2 * R * (1 - 1e-9)
    assert 8.2 * R + e.walls.offset[1, 2] - heights[-1] >= R * (1 - 1e-9)
