"""Time-step suggestion from the contact times of the grains present."""
import math

import numpy as np


def rayleigh_time(radius, density, shear_modulus, poisson_ratio):
    """Rayleigh time T_R = pi R sqrt(rho/G)/(0.1631 nu + 0.8766) [s]."""
    return math.pi * radius * math.sqrt(density / shear_modulus) / (
        0.1631 * poisson_ratio + 0.8766)


# Gear predictor-correctors with a Hertz law: the largest fraction of the Rayleigh time
# they stay stable at, (with the Karrech tangential law, with the others); measured on
# an oblique, spinning grain-grain impact (docs/contact_laws.md, "Stability with the
# Gear predictor-correctors"): Karrech's tangential dashpot on the contact-point
# velocity makes a fast, strongly damped mode that these explicit schemes amplify.
GEAR_HERTZ_FRACTION = {"gear3": (0.1, 0.2), "gear5": (0.05, 0.1), "gear6": (0.02, 0.1)}


def time_step_report(state, materials, model, dt=None, integrator="velocity_verlet"):
    """Critical times of the contact law and the fraction ``dt`` uses of them.

    Hertz laws: the Rayleigh time of the smallest grain of each material (suggested
    dt = 0.2 T_R, rejected above 0.5 T_R; for the Gear schemes both at the fraction of
    GEAR_HERTZ_FRACTION, and ``limit`` says why).  Linear law: the undamped contact
    time pi sqrt(m_min/kn_max) (suggested 1/50, rejected above 1/10 of it), with the
    unloading stiffness kn/e^2 for the plastic Walton-Braun law.
    """
    note = None
    if model.normal == "hertz":
        times = []
        for k, m in enumerate(materials):
            sel = state.materials == k
            if np.any(sel):
                r = float(state.radii[sel].min())
                rho = m.density if state.dim == 3 else m.density / (2 * r)
                times.append(rayleigh_time(r, rho, m.shear_modulus, m.poisson_ratio))
        critical, name, suggest, limit = min(times), "Rayleigh time", 0.2, 0.5
        gear = GEAR_HERTZ_FRACTION.get(integrator)
        if gear is not None:
            karrech = model.tangential == "karrech"
            fraction = gear[0 if karrech else 1]
            suggest = limit = fraction
            note = (f"{integrator}{' with the karrech tangential law' if karrech else ''} "
                    f"was found stable only up to {fraction:.2g} of it")
    else:
        kn = max(m.kn / (m.restitution**2 if model.normal == "walton_braun" else 1.0)
                 for m in materials)
        m_min = float(state.masses.min()) / 2.0
        critical, name, suggest, limit = math.pi * math.sqrt(m_min / kn), \
            "linear contact time", 0.02, 0.1
    report = {"critical_time_s": critical, "criterion": name, "suggested_dt_s": suggest * critical,
              "max_fraction": limit}
    if note is not None:
        report["limit"] = note
    if dt is not None:
        report["dt_s"] = dt
        report["fraction"] = dt / critical
    return report
