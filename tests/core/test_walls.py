"""Walls: prescribed motion, wall forces and stresses, the cylinder, and the contact
stress tensor against the force carried through a column."""
import math

import numpy as np
import pytest

import graindyn as gd
from graindyn.analysis.stress import contact_stress

R = 1e-3
RHO = 2650.0


def _grain_material(**kw):
    return gd.Material(density=RHO, youngs_modulus=1e7, poisson_ratio=0.3, **kw)


def test_sinusoidal_wall_follows_its_law_and_constant_velocity_wall_moves():
    st = gd.State.create([[0, 0, 5 * R]], [R], RHO)
    motion = gd.Motion("sinusoid", direction=(0, 0, 1), amplitude=1e-4, frequency=50.0,
                       phase=0.3)
    walls = [gd.Plane((0, 0, 0), (0, 0, 1), motion=motion),
             gd.Plane((0, 0, 20 * R), (0, 0, -1), motion=gd.Motion("velocity",
                                                                    velocity=(0, 0, -0.01)))]
    sim = gd.Simulation(st, [_grain_material()], gd.ContactModel("hertz"), walls=walls,
                        gravity=(0, 0, 0), dt=1e-6)
    sim.run(steps=3137)
    t = sim.time
    expect = 1e-4 * (math.sin(2 * math.pi * 50 * t + 0.3) - math.sin(0.3))
    assert sim.walls.offset[0, 2] == pytest.approx(expect, rel=1e-9, abs=1e-15)
    assert sim.walls.velocity[0, 2] == pytest.approx(
        1e-4 * 2 * math.pi * 50 * math.cos(2 * math.pi * 50 * t + 0.3), rel=1e-9)
    assert sim.walls.offset[1, 2] == pytest.approx(-0.01 * t, rel=1e-9)


def test_piston_pushes_grain_and_reports_force_and_work():
    """A piston moving down at constant speed onto a sphere resting on the floor (no
    gravity): the floor and the piston carry equal and opposite forces, and the work of
    the piston equals the elastic energy stored (elastic law, quasi-static)."""
    from graindyn.analysis.energy import energy_budget

    st = gd.State.create([[0, 0, R]], [R], RHO)
    walls = [gd.Plane((0, 0, 0), (0, 0, 1), name="floor"),
             gd.Plane((0, 0, 2 * R), (0, 0, -1), name="piston",
                      motion=gd.Motion("velocity", velocity=(0, 0, -1e-3)), area=4 * R * R)]
    sim = gd.Simulation(st, [_grain_material(restitution=0.3)],
                        gd.ContactModel("hertz", "tsuji"), walls=walls, gravity=(0, 0, 0),
                        dt=2e-7)
    sim.run(time=0.01)                                # 10 um of compression
    f_floor = sim.walls.normal_force(0)
    f_piston = sim.walls.normal_force(1)
    assert f_floor > 0
    assert f_piston == pytest.approx(f_floor, rel=1e-3)
    assert sim.walls.stress(1) == pytest.approx(f_piston / (4 * R * R))
    e = energy_budget(sim)
    assert e["wall_work"] == pytest.approx(e["elastic"] + e["dissipated_normal"] + e["kinetic"],
                                           rel=1e-2)
    # each contact takes half the 10 um: Hertz force of a sphere on a plane at 5 um
    e_star = 1e7 / (2 * (1 - 0.3**2))
    assert f_floor == pytest.approx(4 / 3 * e_star * math.sqrt(R) * 5e-6**1.5, rel=2e-2)


def test_free_piston_follows_newtons_law_under_its_applied_force():
    """A piston of mass M with nothing in front of it, pushed by
    F(t) = F0 + F1 sin(w t + phase): x(t) = F0 t^2/(2M) + F1/(M w) (t cos(phase)
    - (sin(w t + phase) - sin(phase))/w), to first order in dt (semi-implicit Euler),
    along its direction only."""
    from graindyn.core.walls import walls_advance

    M, F0, F1, f, phase, dt = 0.2, 3.0, 1.5, 50.0, 0.4, 1e-5
    u = np.array([0.0, 0.6, -0.8])
    kind, row = gd.Motion("piston", direction=tuple(u), force=F0, force_amplitude=F1,
                          frequency=f, phase=phase, mass=M).row()
    w = 2 * math.pi * f
    arrays = (np.array([kind]), row[None, :].copy(), np.zeros((1, 3)), np.zeros((1, 3)),
              np.zeros((1, 3)), np.zeros((1, 3)))
    for n in range(4000):
        walls_advance(*arrays, n * dt, dt)
    t = 4000 * dt
    x = F0 * t**2 / (2 * M) + F1 / (M * w) * (t * math.cos(phase)
                                             - (math.sin(w * t + phase) - math.sin(phase)) / w)
    offset, velocity = arrays[3][0], arrays[4][0]
    np.testing.assert_allclose(offset, x * u, rtol=2e-3)
    v = F0 * t / M + F1 / (M * w) * (math.cos(phase) - math.cos(w * t + phase))
    np.testing.assert_allclose(velocity, v * u, rtol=2e-3)
    assert gd.Motion.from_row(kind, row) == gd.Motion(
        "piston", direction=tuple(u), force=F0, force_amplitude=F1, frequency=f,
        phase=phase, mass=M)


@pytest.mark.parametrize("settings", [dict(mass=0.0), dict(mass=-1.0),
                                      dict(mass=1.0, force_amplitude=-1.0),
                                      dict(mass=1.0, frequency=-1.0),
                                      dict(mass=1.0, force=math.inf)])
def test_piston_refuses_what_has_no_meaning(settings):
    with pytest.raises(ValueError, match="piston motion needs mass > 0"):
        gd.Motion("piston", **settings).row()


def test_grains_stay_inside_a_cylinder(rng):
    from graindyn.protocols.prepare import CylinderRegion, random_insertion

    radii = np.full(60, 0.5e-3)
    pos, radii = random_insertion(radii, CylinderRegion((0, 0), 3e-3, 0, 12e-3), rng)
    st = gd.State.create(pos, radii, RHO, velocities=rng.normal(0, 0.1, (60, 3)))
    walls = [gd.Cylinder((0, 0, 0), (0, 0, 1), 3e-3), gd.Plane((0, 0, 0), (0, 0, 1))]
    sim = gd.Simulation(st, [_grain_material(restitution=0.5, friction_sliding=0.3,
                                             tangential_damping=1.0)],
                        gd.ContactModel("hertz", "tsuji", "mindlin"), walls=walls)
    sim.run(time=0.05)
    rho = np.hypot(st.positions[:, 0], st.positions[:, 1])
    assert np.all(rho + radii < 3e-3 + 0.05 * radii)
    assert np.all(st.positions[:, 2] > 0.95 * radii)


def test_contact_stress_of_a_compressed_column():
    """Two spheres stacked between floor and piston, no gravity: sum f (x) l over the
    contacts equals F H (H the wall gap), so sigma_zz V = F H exactly in equilibrium."""
    st = gd.State.create([[0, 0, R], [0, 0, 3 * R]], [R, R], RHO)
    walls = [gd.Plane((0, 0, 0), (0, 0, 1)),
             gd.Plane((0, 0, 4 * R - 2e-6), (0, 0, -1))]
    sim = gd.Simulation(st, [_grain_material(restitution=0.2)],
                        gd.ContactModel("hertz", "tsuji"), walls=walls, gravity=(0, 0, 0),
                        dt=2e-7)
    sim.run(time=0.02)
    force = sim.walls.normal_force(0)
    height = 4 * R - 2e-6
    volume = 1.0
    sigma = contact_stress(sim, volume)
    assert sigma[2, 2] == pytest.approx(force * height / volume, rel=1e-6)
    assert abs(sigma[0, 0]) < 1e-9 * sigma[2, 2]
