"""Observables of a granular gas: granular temperatures, the pressure from the collision
virial, the collision rate and the velocity distribution, with the equations of state
and the Enskog collision rate of elastic hard spheres and disks to compare them with.

Granular temperature here is kinetic energy per degree of freedom, T = sum m |v - V|^2
/ (d N) [J] (V the mean velocity, d the dimension), the convention of
protocols.prepare.maxwellian_velocities; the rotational one is sum I |w|^2 / (d_r N),
d_r = 3 rotational degrees of freedom for spheres, 1 for disks.
"""
import math

import numpy as np


def _free(state):
    return state.fixed == 0


def granular_temperature(state):
    """(translational, rotational) granular temperature [J] of the free grains (module
    docstring); the translational one about their mass-weighted mean velocity."""
    free = _free(state)
    m = state.masses[free]
    v = state.velocities[free, : state.dim]
    if m.size == 0:
        return 0.0, 0.0
    v = v - (m @ v) / m.sum()
    w = state.angular_velocities[free]
    dof_r = 3 if state.dim == 3 else 1
    translational = float(np.sum(m[:, None] * v * v) / (state.dim * m.size))
    rotational = float(np.sum(state.inertias[free][:, None] * w * w) / (dof_r * m.size))
    return translational, rotational


def collision_pressure(n, temperature, virial, duration, volume, dim):
    """The pressure [Pa] (2D: [N/m]) of a hard-grain gas from the virial theorem,
    P = (N T + W / (d t)) / V, with W [J s] the collision virial sum (r_i - r_j) . J_i
    accumulated over a duration t [s] (EventDriven.virial), T the mean granular
    temperature [J] over it, V the volume [m^3] (2D: area [m^2])."""
    if not duration > 0 or not volume > 0:
        raise ValueError("collision_pressure needs duration > 0 [s] and volume > 0")
    return (n * temperature + virial / (dim * duration)) / volume


def compressibility(phi, dim):
    """The compressibility factor Z = P V / (N T) of elastic hard spheres (Carnahan &
    Starling 1969: (1 + phi + phi^2 - phi^3) / (1 - phi)^3) or disks (Henderson 1975:
    (1 + phi^2/8) / (1 - phi)^2) at packing fraction phi."""
    if dim == 3:
        return (1 + phi + phi**2 - phi**3) / (1 - phi) ** 3
    return (1 + phi**2 / 8) / (1 - phi) ** 2


def contact_value(phi, dim):
    """The pair correlation at contact g(sigma) of the same equations of state:
    Z = 1 + 2^(d-1) phi g(sigma)."""
    return (compressibility(phi, dim) - 1) / (2 ** (dim - 1) * phi)


def enskog_collision_rate(number_density, diameter, temperature, mass, phi, dim):
    """Collisions per grain per second [1/s] of elastic hard spheres (3D: 4 n sigma^2
    g(sigma) sqrt(pi T / m)) or disks (2D: 2 n sigma g(sigma) sqrt(pi T / m)); n the
    number density [1/m^3] ([1/m^2]), sigma the diameter [m], T [J], m [kg].  The
    system's rate is N times this over 2."""
    factor = 4 * diameter**2 if dim == 3 else 2 * diameter
    return factor * number_density * contact_value(phi, dim) * math.sqrt(
        math.pi * temperature / mass)


def velocity_distribution(state, bins=50):
    """The distribution of the free grains' velocity components about their mean,
    scaled by the thermal speed sqrt(T/m) of each grain (T the granular temperature):
    (edges [-], density [-]) of all components pooled, to compare with the standard
    normal law (a Maxwellian) or the overpopulated tails of a cooling gas."""
    free = _free(state)
    v = state.velocities[free, : state.dim]
    v = v - (state.masses[free] @ v) / state.masses[free].sum()
    temperature = granular_temperature(state)[0]
    scaled = v * np.sqrt(state.masses[free][:, None] / temperature)
    density, edges = np.histogram(scaled.reshape(-1), bins=bins, density=True)
    return edges, density
