"""The Gear schemes' time-step guard (engines/soft/timestep.GEAR_HERTZ_FRACTION): at the step
velocity Verlet takes with a Hertz law (0.2 of the Rayleigh time) an oblique, spinning
grain-grain impact with Karrech's tangential dashpot blows up under gear5 and gear6;
at the step the report now suggests for them it conserves energy (kinetic + elastic +
dissipated), and a larger step is refused with the reason."""
import numpy as np
import pytest

import graindyn as gd
from graindyn.analysis.energy import energy_budget

MATERIAL = dict(youngs_modulus=1e7, restitution=0.7, friction_sliding=0.4, alpha_n=0.44,
                alpha_t=0.44)


def impact(integrator, dt=None, allow_large_dt=False):
    """Two spinning spheres (R = 1 mm) meeting obliquely at 1 m/s, no gravity."""
    state = gd.State.create(np.array([[0.0, 0.0, 3e-3], [2.02e-3, 0.3e-3, 3e-3]]),
                            np.full(2, 1e-3), 2650.0,
                            velocities=np.array([[0.5, 0.0, 0.0], [-0.5, 0.0, 0.0]]))
    state.angular_velocities[:] = [[0.0, 0.0, 40.0], [0.0, 0.0, -20.0]]
    return gd.Simulation(state, [gd.Material(**MATERIAL)],
                         gd.ContactModel("hertz", "tsuji", "karrech"), gravity=(0, 0, 0),
                         integrator=integrator, dt=dt, allow_large_dt=allow_large_dt,
                         check_interval=50)


def drift(sim, duration=1.8e-3):
    """Relative change of the energy total over ``duration`` seconds (through the
    whole contact)."""
    before = energy_budget(sim)["total"]
    sim.run(time=duration)
    return energy_budget(sim)["total"] / before - 1.0


@pytest.mark.parametrize("integrator, low", [("gear3", -0.3), ("gear5", -1e-3),
                                             ("gear6", -1e-3)])
def test_gear_schemes_are_stable_at_their_suggested_step(integrator, low, one_thread):
    """No energy is created; gear5 and gear6 keep the total to 1e-3, Karrech's gear3
    (first order, Eq. 4 as printed) loses some."""
    sim = impact(integrator)
    assert sim.dt_report["suggested_dt_s"] < 0.2 * sim.dt_report["critical_time_s"]
    assert low < drift(sim) < 1e-3
    assert len(sim.contacts()[0]) == 0    # the grains met and parted


@pytest.mark.parametrize("integrator", ["gear5", "gear6"])
def test_gear_schemes_blow_up_at_the_velocity_verlet_step(integrator, one_thread):
    t_r = impact("velocity_verlet").dt_report["critical_time_s"]
    assert drift(impact(integrator, 0.2 * t_r, allow_large_dt=True)) > 100.0
    assert abs(drift(impact("velocity_verlet"))) < 0.05


def test_a_gear_step_above_its_safe_fraction_is_refused_with_the_reason():
    t_r = impact("velocity_verlet").dt_report["critical_time_s"]
    with pytest.raises(ValueError, match="gear6 with the karrech tangential law"):
        impact("gear6", 0.1 * t_r)
