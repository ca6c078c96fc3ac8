"""The contact dynamics engine's ``[engine]`` settings and its entry in the engine
registry (engines.ENGINES): how a config's grains, walls and materials become a
ContactDynamics engine.  The contact laws of ``[contact]`` do not apply (rigid grains):
the materials' restitution and friction coefficients are what it reads."""
from typing import Literal

import numpy as np

from ...schema import Float, Int, Section, described as _f
from .. import EngineKind
from .engine import ContactDynamics, suggested_time_step


class ContactDynamicsEngine(Section):
    """Rigid grains by contact dynamics (Moreau-Jean, Pérez Sec. 2): impenetrable
    grains, exact Coulomb friction, Newton restitution, a nonlinear Gauss-Seidel solve
    of the contact impulses every step."""

    kind: Literal["contact_dynamics"] = _f(
        "contact_dynamics", "engine: contact_dynamics (rigid grains, Moreau-Jean)")
    dt: Float | None = _f(None, "time step [s]; default 1/100 of the free-fall time over "
                          "the smallest radius; (0, 1]", gt=0, le=1)
    theta: Float = _f(0.5, "theta of the Moreau-Jean step [-]; 1 is Perez Eq. 11-12, 0.5 "
                      "integrates free flight exactly; [0.5, 1]", ge=0.5, le=1)
    gap: Float | None = _f(None, "contacts closer than this at a step's start are solved "
                           "[m]; default 0.1 of the smallest radius", gt=0)
    tolerance: Float = _f(1e-4, "NLGS convergence: relative impulse change and Signorini "
                          "violation [-]; (0, 0.1]", gt=0, le=0.1)
    max_iterations: Int = _f(1000, "NLGS sweeps per step at most [-]; 1..1e6", ge=1,
                             le=1_000_000)


def build(state, setup, settings: ContactDynamicsEngine):
    """The ContactDynamics engine of ``state`` with ``setup`` (engines.Setup) and
    ``settings``; ValueError on the GPU backend (CPU only)."""
    if setup.backend != "cpu":
        raise ValueError("the contact dynamics engine runs on the CPU only: set "
                         "run.backend = 'cpu'")
    return ContactDynamics(state, setup.materials, walls=setup.walls,
                           periodic=setup.periodic, gravity=setup.gravity, dt=settings.dt,
                           theta=settings.theta, gap=settings.gap,
                           tolerance=settings.tolerance,
                           max_iterations=settings.max_iterations)


def check(state, setup, settings: ContactDynamicsEngine):
    """The time-step report (engine.suggested_time_step) of ``state`` with the fraction
    of the step chosen; ValueError naming engine.dt when it is above the advised tenth
    of the free-fall time, or none can be suggested without gravity."""
    if setup.backend != "cpu":
        raise ValueError("the contact dynamics engine runs on the CPU only: set "
                         "run.backend = 'cpu'")
    if settings.dt is not None and not np.any(setup.gravity):
        return {"criterion": "given time step", "critical_time_s": settings.dt,
                "fraction": 1.0, "max_fraction": 1.0, "suggested_dt_s": settings.dt}
    report = suggested_time_step(state, np.asarray(setup.gravity, dtype=float))
    dt = report["suggested_dt_s"] if settings.dt is None else settings.dt
    report["fraction"] = dt / report["critical_time_s"]
    if report["fraction"] > report["max_fraction"]:
        raise ValueError(
            f"engine.dt = {dt:.3g} s is {report['fraction']:.2f} of the {report['criterion']} "
            f"{report['critical_time_s']:.3g} s; allowed: dt <= "
            f"{report['max_fraction'] * report['critical_time_s']:.3g} s (suggested "
            f"{report['suggested_dt_s']:.3g} s)")
    return report


CONTACT_DYNAMICS = EngineKind(
    "contact_dynamics", ContactDynamicsEngine, build, check,
    "contact dynamics (Moreau-Jean): rigid grains, Signorini, exact Coulomb friction and "
    "Newton restitution solved by nonlinear Gauss-Seidel every step",
    ("fixed", "velocity", "sinusoid", "servo", "piston"), contact_laws=False)
