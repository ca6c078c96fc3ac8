"""Small problems with known solutions for integrator tests and studies (SI units)."""
import math

import numpy as np

from ..core.simulation import Simulation
from ..core.species import ContactModel, Material
from ..core.state import State
from ..core.walls import Plane

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


def hertz_resting_energy_error(integrator, steps_per_period, periods=3, amplitude=0.9):
    """A sphere (default Material) pressed on the plane z = 0 by gravity through an
    elastic Hertz contact, released ``amplitude`` x the equilibrium overlap below
    equilibrium: a smooth anharmonic oscillator that never leaves the plane.
    dt = (small-amplitude period)/steps_per_period.  Returns the largest |E - E0|
    over the run divided by the oscillation energy E0 - E_equilibrium, with E =
    kinetic + gravitational + elastic, against its exact initial value."""
    from ..analysis.energy import energy_budget
    from ..core.triggers import Periodic
    from ..physics import reference as ref

    material = Material()
    mass = 4.0 / 3.0 * math.pi * material.density * RADIUS**3
    e_eff = ref.effective_modulus(material.youngs_modulus, material.poisson_ratio,
                                  material.youngs_modulus, material.poisson_ratio)
    rho = 4.0 / 3.0 * e_eff * math.sqrt(RADIUS)
    overlap_eq = (mass * GRAVITY / rho) ** (2.0 / 3.0)
    omega = math.sqrt(1.5 * rho * math.sqrt(overlap_eq) / mass)
    steps = periods * steps_per_period
    state = State.create(np.array([[0.0, 0.0, RADIUS - (1.0 + amplitude) * overlap_eq]]),
                         np.array([RADIUS]), material.density)
    sim = Simulation(state, [material], ContactModel("hertz", "none", "none"),
                     walls=[Plane((0, 0, 0), (0, 0, 1))], gravity=(0.0, 0.0, -GRAVITY),
                     dt=2.0 * math.pi / omega / steps_per_period, integrator=integrator,
                     allow_large_dt=True)
    z0 = RADIUS - (1.0 + amplitude) * overlap_eq

    def potential(z):
        return mass * GRAVITY * z + 0.4 * rho * max(RADIUS - z, 0.0) ** 2.5

    energies = []
    sim.run(steps=steps, every=[(Periodic(steps=1),
                                 lambda s: energies.append(energy_budget(s)["total"]))])
    e0 = potential(z0)
    return float(np.max(np.abs(np.array(energies) - e0)) / (e0 - potential(RADIUS - overlap_eq)))
