"""An elastic hard-sphere (hard-disk) gas in a periodic box: conservation to round-off,
and the equilibrium pressure and collision rate of the equations of state of Carnahan
and Starling (3D) and Henderson (2D) with Enskog's collision rate."""
import numpy as np
import pytest

import graindyn as gd
from graindyn.analysis import gas
from graindyn.core.walls import Periodic
from graindyn.engines.event_driven.engine import EventDriven
from graindyn.protocols.prepare import BoxRegion, maxwellian_velocities, random_insertion

R = 5e-4            # grain radius [m]
TEMPERATURE = 1e-9  # [J]


def periodic_gas(n, phi, dim, seed=1, restitution=None, **options):
    """n grains of radius R at packing fraction phi in a periodic cube (square), velocities
    Maxwellian at TEMPERATURE with zero momentum, no gravity."""
    rng = np.random.default_rng(seed)
    solid = n * (4 / 3 * np.pi * R**3 if dim == 3 else np.pi * R**2)
    side = (solid / phi) ** (1 / dim)
    positions, radii = random_insertion(np.full(n, R), BoxRegion((0.0,) * dim, (side,) * dim),
                                        rng, dim, periodic=range(dim))
    state = gd.State.create(positions, radii, 2650.0, dim=dim)
    state.velocities[:] = maxwellian_velocities(state.masses, TEMPERATURE, rng, dim)
    engine = EventDriven(state, [gd.Material(restitution=restitution)],
                         periodic=[Periodic(a, 0.0, side) for a in range(dim)],
                         gravity=(0.0, 0.0, 0.0), **options)
    return engine, side**dim


@pytest.mark.parametrize("dim", [3, 2])
def test_an_elastic_gas_conserves_energy_and_momentum_to_round_off(dim):
    """About 1e5 collisions of a dense elastic gas (phi 0.3, 0.45): the kinetic energy
    stays within 1e-12 of its start and the total momentum within 1e-13 of the momentum
    scale N m sqrt(T/m); nothing is dissipated, and no pair overlaps."""
    phi = 0.3 if dim == 3 else 0.45
    engine, volume = periodic_gas(400, phi, dim)
    s = engine.state
    before = engine.energies()["kinetic"]
    scale = s.n * np.sqrt(TEMPERATURE * s.masses[0])
    per_grain = gas.enskog_collision_rate(s.n / volume, 2 * R, TEMPERATURE, s.masses[0],
                                          phi, dim)
    for _ in range(10):                        # 500 collisions per grain, ten pauses
        engine.run(time=100 / per_grain)
    assert engine.energies()["kinetic"] == pytest.approx(before, rel=1e-12)
    assert np.abs(s.masses @ s.velocities).max() < 1e-13 * scale
    energies = engine.energies()
    assert energies["dissipated_normal"] == energies["dissipated_tangential"] == 0.0
    assert engine.contacts().i.size == 0 or np.all(engine.contacts().normal_force == 0)


@pytest.mark.parametrize("dim, phi", [(3, 0.1), (3, 0.3), (2, 0.2), (2, 0.45)])
def test_the_pressure_and_collision_rate_of_an_elastic_gas(dim, phi):
    """The compressibility factor Z = P V / (N T) from the collision virial within 1.5 %
    of Carnahan-Starling (3D) or Henderson (2D), and the collision rate within 2 % of
    Enskog's with the same g(sigma), over about 100 collisions per grain of 1000 grains
    after 20 per grain to equilibrate (the durations sized by Enskog's rate)."""
    engine, volume = periodic_gas(1000, phi, dim, seed=2)
    s = engine.state
    per_grain = gas.enskog_collision_rate(s.n / volume, 2 * R, TEMPERATURE, s.masses[0],
                                          phi, dim)
    engine.run(time=20 / per_grain)
    t0, w0, c0 = engine.time, engine.virial, engine.collisions
    temperature = gas.granular_temperature(s)[0]
    engine.run(time=100 / per_grain)
    duration = engine.time - t0
    assert gas.granular_temperature(s)[0] == pytest.approx(temperature, rel=1e-9)
    pressure = gas.collision_pressure(s.n, temperature, engine.virial - w0, duration,
                                      volume, dim)
    z = pressure * volume / (s.n * temperature)
    assert z == pytest.approx(gas.compressibility(phi, dim), rel=0.015)
    rate = 2 * (engine.collisions - c0) / (s.n * duration)
    assert rate == pytest.approx(gas.enskog_collision_rate(
        s.n / volume, 2 * R, temperature, s.masses[0], phi, dim), rel=0.02)


def test_an_elastic_gas_relaxes_to_the_maxwellian():
    """Grains started at one speed in random directions (far from a Maxwellian) reach
    the Maxwell-Boltzmann distribution after about 10 collisions each: the scaled
    velocity components pass a KS test against the standard normal, and the
    histogram of bins 0.5 wide matches the normal density within 10 % (3 sigma of its
    counts) for |u| < 1.5."""
    from scipy import stats

    engine, volume = periodic_gas(2000, 0.2, 3, seed=3)
    s = engine.state
    rng = np.random.default_rng(4)
    direction = rng.normal(size=(s.n, 3))
    direction /= np.linalg.norm(direction, axis=1)[:, None]
    s.velocities[:] = direction * np.sqrt(3 * TEMPERATURE / s.masses[0])
    s.velocities[:] -= s.velocities.mean(axis=0)
    start = gas.granular_temperature(s)[0]
    scaled = (s.velocities * np.sqrt(s.masses[0] / start)).reshape(-1)
    assert stats.kstest(scaled, "norm").pvalue < 1e-6          # not a Maxwellian yet
    per_grain = gas.enskog_collision_rate(s.n / volume, 2 * R, TEMPERATURE, s.masses[0],
                                          0.2, 3)
    engine.run(time=10 / per_grain)
    temperature = gas.granular_temperature(s)[0]
    scaled = (s.velocities * np.sqrt(s.masses[0] / temperature)).reshape(-1)
    assert stats.kstest(scaled, "norm").pvalue > 1e-3
    edges, density = gas.velocity_distribution(s, bins=np.linspace(-6, 6, 25))
    centres = 0.5 * (edges[1:] + edges[:-1])
    near = np.abs(centres) < 1.5
    np.testing.assert_allclose(density[near], stats.norm.pdf(centres[near]), rtol=0.1)


@pytest.mark.parametrize("dim", [3, 2])
def test_the_straight_flight_loop_gives_the_general_loop_s_numbers(dim):
    """With no gravity and no held grain the event loop runs its copy without those
    terms (EventDriven._straight); forced onto the general copy, the same rough,
    inelastic gas ends with the same positions, velocities and spins to the bit."""
    ends = []
    for straight in (True, False):
        engine, volume = periodic_gas(300, 0.25, dim, restitution=0.9,
                                      tangential_restitution=0.3)
        assert bool(engine._straight())
        if not straight:
            engine._straight = lambda: np.bool_(False)
        s = engine.state
        per_grain = gas.enskog_collision_rate(s.n / volume, 2 * R, TEMPERATURE,
                                              s.masses[0], 0.25, dim)
        engine.run(time=20 / per_grain)
        assert engine.collisions > 1000
        ends.append(np.concatenate([s.positions, s.velocities, s.angular_velocities]))
    np.testing.assert_array_equal(ends[0], ends[1])
