"""Energy balance of a damped, frictional settling run: kinetic + rotational +
gravitational + elastic + dissipated stays constant up to the integrator's error."""
import numpy as np

import graindyn as gd
from graindyn.analysis.energy import energy_budget
from graindyn.protocols.prepare import BoxRegion, random_insertion


def _balance_error(rng, dt_fraction, integrator="velocity_verlet", tangential="cundall_strack"):
    """Largest |total(t) - total(0)| over the run, relative to the potential energy drop."""
    side = 5e-3
    radii = gd.sample_radii(120, "uniform", rng, d_min=0.9e-3, d_max=1.1e-3)
    pos, radii = random_insertion(radii, BoxRegion((0, 0, 0), (side, side, 12e-3)), rng)
    st = gd.State.create(pos, radii, 2650.0)
    m = float(st.masses.mean())
    kn = 2e4 * m * 9.81 / 1e-3                       # 1e-3 d overlap under 2e4 weights
    grain = gd.Material(density=2650.0, kn=kn, kt=2 / 7 * kn, restitution=0.6,
                        friction_sliding=0.4, tangential_damping=2 / 7, friction_static=0.4,
                        friction_rolling=0.05)
    model = gd.ContactModel("hooke", "linear", tangential)
    walls = gd.box((0, 0, 0), (side, side, 20e-3))
    dt = gd.Simulation(st, [grain], model, walls=walls).dt * dt_fraction
    sim = gd.Simulation(st, [grain], model, walls=walls, dt=dt, integrator=integrator)
    budgets = [energy_budget(sim)]
    sim.run(time=0.06, every=[(gd.Periodic(time=0.005), lambda s: budgets.append(
        energy_budget(s)))])
    total = np.array([b["total"] for b in budgets])
    dissipated = budgets[-1]["dissipated_normal"] + budgets[-1]["dissipated_tangential"]
    drop = budgets[0]["gravitational"] - budgets[-1]["gravitational"]
    assert dissipated > 0.5 * drop > 0                 # most of the fall was dissipated
    assert budgets[-1]["dissipated_tangential"] > 0 and budgets[-1]["dissipated_normal"] > 0
    return np.max(np.abs(total - total[0])) / drop


def test_energy_balance_damped_settling():
    """Closes to 1e-3 of the energy released at the suggested step, and the error
    shrinks with the step (at least first order: contact onsets are non-smooth)."""
    coarse = _balance_error(np.random.default_rng(7), 1.0)
    fine = _balance_error(np.random.default_rng(7), 0.25)
    assert coarse < 1e-3
    assert fine < coarse / 3


def test_energy_balance_with_two_force_evaluations_per_step():
    """The optimized velocity Verlet evaluates forces twice per step: each evaluation
    must advance the tangential springs and the dissipation by half a step (counting
    both as whole steps broke the balance by about half of the released energy).
    Its residual falls only as dt (measured 8.4e-3, 4.1e-3, 2.1e-3 at dt, dt/2, dt/4;
    velocity Verlet with predictor: 6.0e-4, 1.5e-4, 4.7e-5): Oquendo Eq. 11-15 give the
    dashpots velocities xi h and (1/2 - xi) h older than the positions, so the scheme is
    first order with velocity-dependent forces (test_integrators.ORDERS), and so is
    the energy it books."""
    coarse = _balance_error(np.random.default_rng(7), 1.0, "optimized_velocity_verlet")
    fine = _balance_error(np.random.default_rng(7), 0.5, "optimized_velocity_verlet")
    assert coarse < 1e-2
    assert coarse / fine > 1.6                     # converges, at least first order


def test_energy_balance_oquendo_literal():
    """The literal reading of Oquendo Eq. 4-10 books what its sliding, rolling and
    memoryless static forces take (-f.v_t dt with the predicted slip, and the rolling
    couple's M.w dt).  The static force is m_t v_t/(2 dt), so an O(dt) error of the
    slip it is booked with is an O(1) share of its work per step: the balance closes
    only to first order (measured 1.4e-2 at the suggested step, 2.2e-3 at a quarter
    of it), and must converge."""
    coarse = _balance_error(np.random.default_rng(7), 1.0, tangential="oquendo_literal")
    fine = _balance_error(np.random.default_rng(7), 0.25, tangential="oquendo_literal")
    assert coarse < 3e-2
    assert fine < coarse / 3
