"""The collision rule of rough hard spheres and disks against Pérez Eq. 1-10 written out
literally, and against the conservation laws it is built on."""
import math

import numpy as np
import pytest

import graindyn as gd
from graindyn.engines.event_driven.collision import collision_impulse, contact_velocity
from graindyn.engines.event_driven.engine import EventDriven

RESTITUTIONS = [(1.0, 1.0), (1.0, -1.0), (0.8, 0.3), (0.5, -0.6), (0.05, 0.0), (0.9, 1.0)]


def perez(ma, mb, ra, rb, ia, ib, va, vb, wa, wb, ra_pos, rb_pos, e_n, e_s):
    """Pérez Eq. 1-10 as printed: the velocities and spins after the collision."""
    dr = rb_pos - ra_pos                                           # Eq. 1
    n = dr / np.linalg.norm(dr)
    v_ab = va - vb + np.cross(ra * wa + rb * wb, n)                # Eq. 2
    v_n = (v_ab @ n) * n                                           # Eq. 3
    v_s = v_ab - v_n                                               # Eq. 4
    red_a, red_b = ia / (ma * ra**2), ib / (mb * rb**2)
    S = ma + mb                                                    # Eq. 7
    T = ma * (1 + red_b) / red_b + mb * (1 + red_a) / red_a
    D = -(1 + e_n) / S * v_n + (e_s - 1) / T * v_s                 # Eq. 8
    return (va + mb * D, wa + mb / (ra * red_a) * np.cross(n, D),  # Eq. 9
            vb - ma * D, wb + ma / (rb * red_b) * np.cross(n, D))  # Eq. 10


def contact_point_velocity(n, va, vb, wa, wb, ra, rb):
    return va - vb + np.cross(ra * wa + rb * wb, n)


def turned(q, w, t):
    """The unit quaternion q (w, x, y, z) after turning at constant spin w [rad/s] for t
    [s]: the Hamilton product (cos(a/2), sin(a/2) w/|w|) q, a = |w| t."""
    a = np.linalg.norm(w) * t
    axis = w / np.linalg.norm(w)
    p0, (p1, p2, p3) = math.cos(a / 2), math.sin(a / 2) * axis
    q0, q1, q2, q3 = q
    return np.array([p0 * q0 - p1 * q1 - p2 * q2 - p3 * q3,
                     p0 * q1 + p1 * q0 + p2 * q3 - p3 * q2,
                     p0 * q2 - p1 * q3 + p2 * q0 + p3 * q1,
                     p0 * q3 + p1 * q2 - p2 * q1 + p3 * q0])


@pytest.mark.parametrize("dim", [3, 2])
@pytest.mark.parametrize("e_n, e_s", RESTITUTIONS)
def test_a_collision_in_the_engine_follows_perez(dim, e_n, e_s):
    """Two grains of different size and density thrown at each other off-centre with
    spin: after the engine's collision their velocities and spins are Eq. 9-10's (1e-12),
    the contact points' relative velocity is (-e_n v_n, e_s v_s) of Eq. 5-6, and linear
    momentum and the angular momentum about the contact point are conserved.  Run in
    two parts, the collision in the second: each grain's orientation is turned at its
    spin before the collision until it, and at its spin after from then on."""
    rng = np.random.default_rng(7 + dim)
    ra, rb = 1e-3, 1.6e-3
    dirn = np.array([1.0, 0.35, 0.2 if dim == 3 else 0.0])
    dirn /= np.linalg.norm(dirn)
    pa = np.zeros(3)
    pb = pa + (ra + rb) * dirn * (1 + 1e-3)
    va = np.array([0.3, 0.1, 0.05 if dim == 3 else 0.0])
    vb = np.array([-0.2, 0.05, -0.02 if dim == 3 else 0.0])
    wa = rng.normal(0, 200, 3) if dim == 3 else np.array([0, 0, 150.0])
    wb = rng.normal(0, 200, 3) if dim == 3 else np.array([0, 0, -80.0])
    state = gd.State.create([pa, pb], [ra, rb], [2650.0, 7800.0], dim=dim,
                            velocities=[va, vb])
    state.angular_velocities[:] = [wa, wb]
    engine = EventDriven(state, [gd.Material(restitution=e_n)], gravity=(0, 0, 0),
                         tangential_restitution=e_s)
    s = state
    m, inertia = s.masses.copy(), s.inertias.copy()
    # the collision time and place, from the straight-line approach
    d, u = pa - pb, va - vb
    b, c, a = d @ u, d @ d - (ra + rb) ** 2, u @ u
    t = c / (-b + math.sqrt(b * b - a * c))
    at_a, at_b = pa + va * t, pb + vb * t
    engine.run(time=t * 0.7)
    assert engine.collisions == 0
    engine.run(time=t * 0.8)
    assert engine.collisions == 1
    want = perez(m[0], m[1], ra, rb, inertia[0], inertia[1], va, vb, wa, wb, at_a, at_b,
                 e_n, e_s)
    for got, expected in zip((s.velocities[0], s.angular_velocities[0], s.velocities[1],
                              s.angular_velocities[1]), want):
        np.testing.assert_allclose(got, expected, rtol=1e-10, atol=1e-12 * np.abs(
            expected).max() + 1e-14)
    n = (at_b - at_a) / np.linalg.norm(at_b - at_a)
    before = contact_point_velocity(n, va, vb, wa, wb, ra, rb)
    after = contact_point_velocity(n, want[0], want[2], want[1], want[3], ra, rb)
    b_n = (before @ n) * n
    np.testing.assert_allclose((after @ n) * n, -e_n * b_n, atol=1e-12)
    np.testing.assert_allclose(after - (after @ n) * n, e_s * (before - b_n), atol=1e-12)
    p_before = m[0] * va + m[1] * vb
    p_after = m[0] * s.velocities[0] + m[1] * s.velocities[1]
    np.testing.assert_allclose(p_after, p_before, rtol=1e-13, atol=1e-18)
    contact = at_a + ra * n
    def angular(vel, spin):
        return sum(np.cross(x - contact, m[k] * vel[k]) + inertia[k] * spin[k]
                   for k, x in enumerate((at_a, at_b)))
    np.testing.assert_allclose(angular(s.velocities, s.angular_velocities),
                               angular((va, vb), (wa, wb)), rtol=1e-10, atol=1e-20)
    for k, spin in enumerate((wa, wb)):
        expected = turned(turned(np.array([1.0, 0, 0, 0]), spin, t), want[2 * k + 1],
                          0.5 * t)
        np.testing.assert_allclose(s.orientations[k], expected, atol=1e-12)


def test_the_energy_lost_splits_into_its_normal_and_tangential_parts():
    """collision_impulse's dE_n + dE_s is the kinetic energy lost, and each part is zero
    in its elastic limit (e_n = 1; e_s = +1 or -1)."""
    rng = np.random.default_rng(1)
    for _ in range(50):
        n = rng.normal(size=3)
        n /= np.linalg.norm(n)
        v = rng.normal(size=3)
        v += (abs(v @ n) + 0.1) * n - (v @ n) * n            # approaching: v . n > 0
        e_n, e_s = rng.uniform(0, 1), rng.uniform(-1, 1)
        ma, mb, ra, rb = 2.0, 3.0, 0.5, 0.7
        ia, ib = 0.4 * ma * ra**2, 0.4 * mb * rb**2
        j = np.array(collision_impulse(*n, *v, 1 / ma + 1 / mb, ra**2 / ia + rb**2 / ib,
                                       e_n, e_s))
        impulse, dn, ds = j[:3], j[3], j[4]
        # grain b at rest, grain a at v (no spin): the energy change of the pair
        va, vb = v, np.zeros(3)
        wa_new = ra * np.cross(n, impulse) / ia
        wb_new = rb * np.cross(n, impulse) / ib
        before = 0.5 * ma * va @ va
        after = 0.5 * ma * np.sum((va + impulse / ma) ** 2) + 0.5 * mb * np.sum(
            (vb - impulse / mb) ** 2) + 0.5 * ia * wa_new @ wa_new + 0.5 * ib * wb_new @ wb_new
        assert before - after == pytest.approx(dn + ds, rel=1e-9, abs=1e-15)
    for e_s in (1.0, -1.0):
        out = collision_impulse(1.0, 0.0, 0.0, 1.0, 0.5, 0.0, 1.0, 1.0, 1.0, e_s)
        assert out[3] == 0.0 and out[4] == pytest.approx(0.0, abs=1e-16)


def test_separating_contact_points_exchange_nothing():
    assert collision_impulse(1.0, 0.0, 0.0, -0.5, 0.3, 0.0, 1.0, 1.0, 0.5, 0.0)[:3] == \
        (0.0, 0.0, 0.0)
    assert contact_velocity(1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0,
                            0.0, 0.0, 0.0, 0.0, 1.0) == (0.0, 1.0, 0.0)
