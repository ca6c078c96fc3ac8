"""Every registered law through the compiled dispatcher physics.contact.contact_force,
called directly (no simulation): zero force at zero overlap, Newton's third law for
forces and couples, Walton-Braun restitution = input on an integrated 1D collision,
and the Elata-Berryman correction of the Mindlin spring (no energy from closed
loading paths).  Truths are analytic; nothing is compared with the code's own output.
"""
import itertools
import math

import numpy as np
import pytest

import graindyn as gd
from graindyn.physics import registry
from graindyn.physics.contact import contact_energy, contact_force
from graindyn.physics.tangential import tangential_planar_spring_force, tangential_spring_force

R = 1e-3                 # m
M = 1e-5                 # kg, reduced mass
MATERIAL = dict(density=2500.0, youngs_modulus=1e9, poisson_ratio=0.25, restitution=0.7,
                kn=1e5, kt=3e4, friction_sliding=0.3, friction_static=0.4,
                friction_rolling=0.1, tangential_damping=0.0, gamma_nt=50.0, alpha_n=0.3,
                alpha_t=0.3, rolling_stiffness=1e4, rolling_damping=1e-2,
                friction_twisting=0.2, twisting_stiffness=1e-3, twisting_damping=1e-7,
                gamma_n=1e3)


def _setup(material=None, **laws):
    model = gd.ContactModel(**laws)
    params = model.pair_table([gd.Material(**(material or MATERIAL))])
    return model.ids(), params, np.zeros((1, max(1, model.history_size)))


def _force(ids, params, history, overlap, n, v, w_lever, w_rel, dt=1e-7, lever_i=R,
           lever_j=R):
    """contact_force with the contact-point velocity of contacts.contact_response."""
    n = np.asarray(n, float)
    v = np.asarray(v, float) - np.cross(w_lever, n)
    vn = float(v @ n)
    vt = v - vn * n
    return contact_force(ids, params, 0, 0, overlap, R / 2, lever_i, lever_j, M, n[0], n[1],
                         n[2], vn, vt[0], vt[1], vt[2], w_rel[0], w_rel[1], w_rel[2], history,
                         0, dt)


ALL = [dict(zip(registry.MODES, names)) for names in itertools.product(
    *[[law.name for law in registry.laws(mode)] for mode in registry.MODES])]


def _valid(laws):
    try:
        gd.ContactModel(**laws).check([gd.Material(**MATERIAL)])
    except ValueError:
        return False
    # a dashpot with a constant coefficient (linear; tsuji and karrech on a linear
    # spring) gives c v at first touch: the one place a force does not start at zero
    return laws["damping"] == "none" or (laws["normal"] == "hertz" and laws["damping"] != "linear")


VALID = [laws for laws in ALL if _valid(laws)]


def test_every_law_is_covered():
    """Every registered law takes part in the checks below (the linear dashpot, whose
    force jumps to c v at first touch, is the one law left out; it has A1)."""
    for mode in registry.MODES:
        assert {laws[mode] for laws in VALID} == \
            {law.name for law in registry.laws(mode)} - {"linear"}


@pytest.mark.parametrize("laws", VALID, ids=lambda d: "-".join(d.values()))
def test_zero_force_at_zero_overlap_and_third_law(laws):
    """At xi = 0 every force and couple vanishes; for xi > 0 swapping i and j (n, v, w
    reversed, same fresh history) reverses the force and the couple, so the forces
    are equal and opposite and the torques cancel about the contact point."""
    ids, params, history = _setup(**laws)
    rng = np.random.default_rng(3)
    n = rng.normal(size=3)
    n /= np.linalg.norm(n)
    v, wl, wr = rng.normal(size=3) * 0.1, rng.normal(size=3) * 1e-4, rng.normal(size=3) * 100
    out = _force(ids, params, history, 0.0, n, v, wl, wr)
    assert np.all(np.array(out[:7]) == 0.0), out
    history[:] = 0.0
    a = np.array(_force(ids, params, history, 1e-6, n, v, wl, wr))
    history[:] = 0.0
    b = np.array(_force(ids, params, history, 1e-6, -n, -v, wl, -wr))
    assert a[0] > 0 and b[0] == pytest.approx(a[0], rel=1e-12)      # |f_n| the same
    assert b[1:7] == pytest.approx(-a[1:7], rel=1e-9, abs=1e-300)   # f_t and M reversed
    assert a[7] >= 0 and a[8] >= 0                                  # dissipation >= 0
    # (tangential_damping = 0: the Cundall-Strack cap books a negative loss when the
    # dashpot alone exceeds it, see tangential_spring_force)


def _collide(laws, e, steps_per_contact=4000, v=1.0, kn=1e5):
    """Head-on 1D collision of a pair of reduced mass M integrated with velocity
    Verlet around contact_force; returns the restitution v_out/v_in."""
    ids, params, history = _setup(dict(MATERIAL, restitution=e, kn=kn), **laws)
    dt = math.pi * math.sqrt(M / kn) / steps_per_contact
    x, u = -0.5 * v * dt, v           # overlap and its rate; touch mid-step
    f = 0.0
    for _ in range(100 * steps_per_contact):
        u += 0.5 * dt * (-f / M)
        x += u * dt
        f = _force(ids, params, history, x, (1, 0, 0), (-u, 0, 0), (0, 0, 0), (0, 0, 0),
                   dt)[0] if x > 0 else 0.0
        u += 0.5 * dt * (-f / M)
        if x < 0 and u < 0:
            return -u / v
    raise AssertionError("no separation")


@pytest.mark.parametrize("normal", ["walton_braun", "walton_braun_silo"])
@pytest.mark.parametrize("e", [0.2, 0.5, 0.9, 1.0])
def test_walton_braun_restitution_is_input(normal, e):
    """Both Walton-Braun variants: v_out/v_in = e (the input) within 1e-3 at any speed."""
    for v in (0.01, 1.0):
        assert _collide(dict(normal=normal), e, v=v) == pytest.approx(e, abs=1e-3)


def test_walton_braun_plastic_force_vanishes_at_finite_overlap():
    """Fig. 2a: unloading from xi_max along kn/e^2 reaches f = 0 at xi_max (1 - e^2)."""
    e, kn, peak = 0.6, 1e5, 1e-5
    ids, params, history = _setup(dict(MATERIAL, restitution=e, kn=kn), normal="walton_braun")
    f_peak = _force(ids, params, history, peak, (0, 0, 1), (0, 0, -1), (0,) * 3, (0,) * 3)[0]
    assert f_peak == pytest.approx(kn * peak, rel=1e-12)
    x0 = peak * (1 - e * e)
    mid = 0.5 * (peak + x0)
    f_mid = _force(ids, params, history, mid, (0, 0, 1), (0, 0, 1), (0,) * 3, (0,) * 3)[0]
    assert f_mid == pytest.approx(kn / e**2 * (mid - x0), rel=1e-12)
    f_below = _force(ids, params, history, 0.9 * x0, (0, 0, 1), (0, 0, 1), (0,) * 3, (0,) * 3)
    assert f_below[0] == 0.0


# ----------------------------------------------------------- Elata-Berryman
def _cycle_work(laws, path, mu=10.0, naive=False):
    """Drive a contact quasi-statically (no dashpots) along a closed (xi, delta_t) path;
    return the work the driver does on it, -sum f.d(delta) (>= 0 for a law that never
    gives energy back), and the stored energy at the end."""
    ids, params, history = _setup(dict(MATERIAL, friction_sliding=mu, tangential_damping=0.0,
                                       alpha_t=0.0), **laws)
    g = params[0, 0, registry.COL["shear_eff"]]
    work, xi_prev, t_prev = 0.0, path[0][0], path[0][1]
    f_prev = np.zeros(3)
    dt = 1.0
    for xi, t in path[1:]:
        dxi, dtt = xi - xi_prev, t - t_prev
        # grain i moves by (dt_t along x, -dxi along the normal z)
        if naive:   # the plain incremental spring: kt follows a, zeta is never rescaled
            kt = 8 * g * math.sqrt(R / 2 * xi)
            f = tangential_spring_force(kt, 0.0, mu, 1e9, 0, 0, 0, 1, dtt / dt, 0, 0, history,
                                        0, 0, dt)
            f = np.array([f[0], 0.0, 0.0])
        else:
            out = _force(ids, params, history, xi, (0, 0, 1), (dtt / dt, 0, -dxi / dt),
                         (0,) * 3, (0,) * 3, dt)
            f = np.array([out[1], out[2], out[3]])
        # trapezoid of the tangential force over the increment (normal force conservative)
        work -= 0.5 * (f + f_prev)[0] * dtt
        f_prev, xi_prev, t_prev = f, xi, t
    stored = contact_energy(ids, params, 0, 0, path[-1][0], R / 2, history, 0) - \
        contact_energy(ids, params, 0, 0, path[-1][0], R / 2, np.zeros_like(history), 0)
    return work, stored


def _loop(forward, cycles=5, n=200):
    """A (xi1, 0) -> B (xi1, u) -> C (xi0, u) -> D (xi0, 0) -> A, or the reverse."""
    xi0, xi1, u = 2e-7, 2e-6, 1e-7
    corners = [(xi1, 0.0), (xi1, u), (xi0, u), (xi0, 0.0), (xi1, 0.0)]
    if not forward:
        corners = corners[::-1]
    path = [corners[0]]
    for _ in range(cycles):
        for (a0, b0), (a1, b1) in zip(corners[:-1], corners[1:]):
            s = np.linspace(0, 1, n + 1)[1:]
            path += list(zip(a0 + (a1 - a0) * s, b0 + (b1 - b0) * s))
    return path


@pytest.mark.parametrize("tangential", ["mindlin", "karrech", "oquendo"])
@pytest.mark.parametrize("forward", [True, False])
@pytest.mark.parametrize("mu", [10.0, 0.2])
def test_mindlin_closed_paths_create_no_energy(tangential, forward, mu):
    """Karrech Sec. 2 (Elata & Berryman; Roux & Chevoir): over closed loading paths in
    (normal, tangential) displacement, with and without slip, the driver never gets
    energy back: work done on the contact >= what remains stored in it."""
    work, stored = _cycle_work(dict(normal="hertz", tangential=tangential), _loop(forward),
                               mu=mu)
    assert work >= stored - 1e-12 * abs(work)
    assert stored >= 0


def test_closed_path_check_catches_the_naive_mindlin_spring():
    """The same check fails for the uncorrected incremental spring (the test is not
    void): going round one way it hands back energy it never received."""
    works = [_cycle_work(dict(normal="hertz", tangential="mindlin"), _loop(fw), naive=True)[0]
             for fw in (True, False)]
    assert min(works) < 0


@pytest.mark.parametrize("cap", [0, 1, 2])
def test_planar_spring_is_the_vector_spring_of_a_disk(cap):
    """Perez Eq. 20-23 in 2D: the scalar elongation along s = z x n
    (tangential_planar_spring_force) against the vector spring turned into each new
    tangent with its length kept (tangential_spring_force), over a contact whose normal
    turns 0.02 rad a step while its slip reverses (sticking, then sliding at the cap
    both ways, with a dashpot): the same forces and losses to rounding, and the vector
    spring is the scalar one along s at every step."""
    kt, eta, mu, dt = 3e4, 0.5, 0.3, 1e-5
    vector = np.zeros((1, 3))
    planar = np.zeros((1, 3))
    capped = 0
    for step in range(400):
        angle = 0.02 * step
        nx, ny = math.cos(angle), math.sin(angle)
        fn = 2.0 + math.sin(0.05 * step)
        slip = 0.4 * math.sin(0.03 * step)                 # m/s along s
        vtx, vty = -ny * slip, nx * slip
        fv = tangential_spring_force(kt, eta, mu, fn, cap, nx, ny, 0.0, vtx, vty, 0.0,
                                     vector, 0, 0, dt)
        fp = tangential_planar_spring_force(kt, eta, mu, fn, cap, nx, ny, vtx, vty, planar,
                                            0, 0, dt)
        scale = mu * fn + eta * abs(slip)
        for d in range(3):
            assert abs(fv[d] - fp[d]) <= 1e-12 * scale
        assert abs(fv[3] - fp[3]) <= 1e-12 * scale * abs(slip) * dt + 1e-30
        assert np.allclose(vector[0], planar[0, 0] * np.array([-ny, nx, 0.0]),
                           rtol=0.0, atol=1e-12 * mu * fn / kt)
        assert planar[0, 1] == planar[0, 2] == 0.0
        capped += math.hypot(fp[0], fp[1]) >= mu * fn * (1 - 1e-12)
    assert 20 < capped < 380                              # it stuck and it slid
