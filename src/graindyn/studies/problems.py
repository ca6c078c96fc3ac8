"""Small problems with known solutions for integrator tests and studies (SI units)."""
import math

import numpy as np

from ..core.species import ContactModel, Material
from ..core.state import State
from ..core.walls import Plane
from ..core.rotation import quaternion_leapfrog
from ..engines.soft.simulation import Simulation

RADIUS = 0.01       # m
DENSITY = 1000.0    # kg/m^3
KN = 1e4            # N/m
GRAVITY = 100.0     # m/s^2: equilibrium overlap m g/kn = 0.4 % of R


def resting_grain(integrator, dt, damping_constant=0.0, amplitude=0.5):
    """A sphere pressed on the plane z = 0 by gravity, linear spring (and dashpot
    damping_constant [kg/s]), released ``amplitude`` x the equilibrium overlap below
    equilibrium: it oscillates about equilibrium without ever leaving the plane, a
    smooth damped harmonic oscillator.  Returns (simulation, exact(t) -> (z [m],
    v_z [m/s]), scale (amplitude [m], amplitude x omega0 [m/s]))."""
    mass = 4.0 / 3.0 * math.pi * DENSITY * RADIUS**3
    omega0 = math.sqrt(KN / mass)
    gamma = damping_constant / (2.0 * mass)
    omega = math.sqrt(omega0**2 - gamma**2)
    z_eq = RADIUS - mass * GRAVITY / KN
    x0 = -amplitude * mass * GRAVITY / KN
    state = State.create(np.array([[0.0, 0.0, z_eq + x0]]), np.array([RADIUS]), DENSITY)
    material = Material(kn=KN, damping_constant=damping_constant)
    model = ContactModel("hooke", "linear" if damping_constant > 0 else "none", "none")
    sim = Simulation(state, [material], model, walls=[Plane((0, 0, 0), (0, 0, 1))],
                     gravity=(0.0, 0.0, -GRAVITY), dt=dt, integrator=integrator,
                     allow_large_dt=True)

    def exact(t):
        decay = math.exp(-gamma * t)
        z = z_eq + decay * x0 * (math.cos(omega * t) + gamma / omega * math.sin(omega * t))
        v = -decay * x0 * omega0**2 / omega * math.sin(omega * t)
        return z, v

    return sim, exact, (abs(x0), abs(x0) * omega0)


def oscillation_period(damping_constant=0.0):
    """Period 2 pi/omega [s] of resting_grain."""
    mass = 4.0 / 3.0 * math.pi * DENSITY * RADIUS**3
    return 2.0 * math.pi / math.sqrt(KN / mass - (damping_constant / (2.0 * mass))**2)


def resting_grain_error(integrator, steps_per_period, periods=2, damping_constant=0.0):
    """Largest of |z - z_exact|/amplitude and |v - v_exact|/(amplitude omega0) after
    ``periods`` periods of resting_grain."""
    dt = oscillation_period(damping_constant) / steps_per_period
    sim, exact, (x_scale, v_scale) = resting_grain(integrator, dt, damping_constant)
    sim.run(steps=periods * steps_per_period)
    z, v = exact(sim.time)
    return max(abs(sim.state.positions[0, 2] - z) / x_scale,
               abs(sim.state.velocities[0, 2] - v) / v_scale)


def hertz_bounce(integrator, steps_per_collision, speed=1.0, onset=3.5):
    """Elastic Hertz sphere (default Material) hitting the plane z = 0 at ``speed``
    [m/s], g = 0, dt = t_c/steps_per_collision with t_c the Hertz collision time
    (physics.reference); first touch ``onset`` steps after the start.  Returns
    |e - 1|, e the restitution coefficient (exactly 1 for the elastic law)."""
    from ..physics import reference as ref

    material = Material()
    mass = 4.0 / 3.0 * math.pi * material.density * RADIUS**3
    e_eff = ref.effective_modulus(material.youngs_modulus, material.poisson_ratio,
                                  material.youngs_modulus, material.poisson_ratio)
    t_c = ref.hertz_collision_time(mass, RADIUS, e_eff, speed)
    dt = t_c / steps_per_collision
    state = State.create(np.array([[0.0, 0.0, RADIUS + onset * speed * dt]]),
                         np.array([RADIUS]), material.density,
                         velocities=np.array([[0.0, 0.0, -speed]]))
    sim = Simulation(state, [material], ContactModel("hertz", "none", "none"),
                     walls=[Plane((0, 0, 0), (0, 0, 1))], gravity=(0.0, 0.0, 0.0), dt=dt,
                     integrator=integrator, allow_large_dt=True)
    sim.run(steps=int(onset + 1.5 * steps_per_collision))
    while sim.state.positions[0, 2] < RADIUS:
        sim.run(steps=steps_per_collision)
    return abs(sim.state.velocities[0, 2] / speed - 1.0)


def hertz_resting_oscillator(steps_per_period, amplitude=0.9):
    """The oscillator of hertz_resting_energy_error: a sphere (default Material, radius
    RADIUS) on the plane z = 0 under gravity GRAVITY, Hertz force rho (R - z)^1.5.
    Returns a dict: ``material``, ``mass`` [kg], ``rho`` [N/m^1.5], ``z0`` [m] (released
    at rest ``amplitude`` x the equilibrium overlap below equilibrium), ``z_eq`` [m],
    ``dt`` [s] (small-amplitude period / steps_per_period) and ``potential(z)`` [J]."""
    from ..physics import reference as ref

    material = Material()
    mass = 4.0 / 3.0 * math.pi * material.density * RADIUS**3
    e_eff = ref.effective_modulus(material.youngs_modulus, material.poisson_ratio,
                                  material.youngs_modulus, material.poisson_ratio)
    rho = 4.0 / 3.0 * e_eff * math.sqrt(RADIUS)
    overlap_eq = (mass * GRAVITY / rho) ** (2.0 / 3.0)
    omega = math.sqrt(1.5 * rho * math.sqrt(overlap_eq) / mass)

    def potential(z):
        return mass * GRAVITY * z + 0.4 * rho * max(RADIUS - z, 0.0) ** 2.5

    return {"material": material, "mass": mass, "rho": rho,
            "z0": RADIUS - (1.0 + amplitude) * overlap_eq, "z_eq": RADIUS - overlap_eq,
            "dt": 2.0 * math.pi / omega / steps_per_period, "potential": potential}


def hertz_resting_energy_error(integrator, steps_per_period, periods=3, amplitude=0.9):
    """A sphere (default Material) pressed on the plane z = 0 by gravity through an
    elastic Hertz contact, released ``amplitude`` x the equilibrium overlap below
    equilibrium: a smooth anharmonic oscillator that never leaves the plane
    (hertz_resting_oscillator).  dt = (small-amplitude period)/steps_per_period.
    Returns the largest |E - E0| over the run divided by the oscillation energy
    E0 - E_equilibrium, with E = kinetic + gravitational + elastic, against its exact
    initial value."""
    from ..analysis.energy import energy_budget
    from ..core.triggers import Periodic

    o = hertz_resting_oscillator(steps_per_period, amplitude)
    state = State.create(np.array([[0.0, 0.0, o["z0"]]]), np.array([RADIUS]),
                         o["material"].density)
    sim = Simulation(state, [o["material"]], ContactModel("hertz", "none", "none"),
                     walls=[Plane((0, 0, 0), (0, 0, 1))], gravity=(0.0, 0.0, -GRAVITY),
                     dt=o["dt"], integrator=integrator, allow_large_dt=True)
    energies = []
    sim.run(steps=periods * steps_per_period,
            every=[(Periodic(steps=1), lambda s: energies.append(energy_budget(s)["total"]))])
    e0 = o["potential"](o["z0"])
    return float(np.max(np.abs(np.array(energies) - e0)) / (e0 - o["potential"](o["z_eq"])))


def _rotate(q, v):
    """R(q) v: body-frame vector v in the world frame, q = (w, x, y, z)."""
    u = np.asarray(q[1:])
    t = 2.0 * np.cross(u, v)
    return v + q[0] * t + np.cross(u, t)


def symmetric_top(dt_omega=0.01, periods=10.0, inertia=(1.0, 1.0, 2.0),
                  omega=(0.3, 0.0, 1.0)):
    """A torque-free rigid body with principal moments ``inertia`` (I1 = I2 != I3: a
    symmetric top) and initial body-frame angular velocity ``omega`` [rad/s], advanced
    by Omelyan's leap-frog: body-frame w at half steps from Euler's equations
    I dw/dt = (I w) x w with the right side at the mean of the two half-step values
    (implicit, solved by fixed-point iteration; Omelyan, PRE 58, 1169, 1998), and q by
    the engine's quaternion leap-frog (Oquendo Eq. 18).  dt = dt_omega/|w|; the run
    covers ``periods`` body-frame precession periods 2 pi/W, W = w3 (I3 - I1)/I1
    (unit inertia: any consistent units).  Grains in graindyn are isotropic, so this is
    where the anisotropic check of VALIDATION G2 lives.

    Returns a dict of arrays: ``time`` (whole steps), ``omega_body`` (N x 3, mean of
    the half steps around each whole step), ``energy`` ½ w.I w, ``angular_momentum``
    (N x 3, world frame, R(q) I w) and the precession rate ``W``."""
    inertia = np.asarray(inertia, dtype=float)
    w = np.asarray(omega, dtype=float)
    dt = dt_omega / np.linalg.norm(w)
    rate = w[2] * (inertia[2] - inertia[0]) / inertia[0]
    steps = int(round(periods * 2.0 * math.pi / abs(rate) / dt))
    q = (1.0, 0.0, 0.0, 0.0)
    leapfrog = quaternion_leapfrog.py_func
    # start-up: w(-dt/2) from w(0) by half an implicit step backwards
    w_half = _euler_step(w, inertia, -0.5 * dt)
    out = {"time": [], "omega_body": [], "energy": [], "angular_momentum": []}
    for n in range(steps + 1):
        w_next = _euler_step(w_half, inertia, dt)
        w_mean = 0.5 * (w_half + w_next)
        out["time"].append(n * dt)
        out["omega_body"].append(w_mean)
        out["energy"].append(0.5 * w_mean @ (inertia * w_mean))
        out["angular_momentum"].append(_rotate(q, inertia * w_mean))
        q = leapfrog(*q, *_rotate(q, w_next), dt)
        w_half = w_next
    result = {key: np.array(value) for key, value in out.items()}
    result["W"] = rate
    return result


def symmetric_top_errors(dt_omega):
    """Errors of symmetric_top(dt_omega): ``precession_rate_error`` (fitted body-frame
    precession rate over W, minus 1), ``energy_spread`` and
    ``angular_momentum_norm_spread`` (peak to peak over the initial value), and
    ``world_angular_momentum_error``: the largest |L(t) - L(0)|/|L(0)| in the first and
    in the second half of the run (equal when the error is bounded, not drifting)."""
    top = symmetric_top(dt_omega)
    w, t = top["omega_body"], top["time"]
    rate = np.polyfit(t, np.unwrap(np.arctan2(w[:, 1], w[:, 0])), 1)[0]
    ang = top["angular_momentum"]
    size = np.linalg.norm(ang, axis=1)
    drift = np.linalg.norm(ang - ang[0], axis=1) / size[0]
    half = len(t) // 2
    return {"precession_rate_error": float(rate / top["W"] - 1.0),
            "energy_spread": float(np.ptp(top["energy"]) / top["energy"][0]),
            "angular_momentum_norm_spread": float(np.ptp(size) / size[0]),
            "world_angular_momentum_error": [float(drift[:half].max()),
                                             float(drift[half:].max())]}


def _euler_step(w, inertia, dt):
    """Implicit-midpoint step of Euler's torque-free equations in the body frame:
    w' = w + dt I^-1 [(I m) x m], m = (w + w')/2, iterated to round-off."""
    nxt = w.copy()
    for _ in range(100):
        m = 0.5 * (w + nxt)
        new = w + dt * np.cross(inertia * m, m) / inertia
        if np.array_equal(new, nxt):
            break
        nxt = new
    return nxt
