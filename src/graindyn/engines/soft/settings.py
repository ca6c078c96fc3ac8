"""The soft engine's ``[engine]`` settings and its entry in the engine registry
(engines.ENGINES): how a config's grains, walls and laws become a Simulation."""
from typing import Literal

from pydantic import field_validator

from ...schema import Float, Int, Section, described as _f
from .. import EngineKind
from .integrators import integrator_id
from .simulation import Simulation
from .timestep import time_step_report


class SoftEngine(Section):
    """The time-driven soft-particle engine (Simulation): grains overlap a little, the
    contact laws give forces, an explicit integrator advances them by a fixed step."""

    kind: Literal["soft"] = _f("soft", "engine: soft (time-driven soft particles)")
    integrator: str = _f("velocity_verlet", "integrator (see graindyn info)")
    dt: Float | None = _f(None, "time step [s]; default: the suggested step; (0, 1]", gt=0,
                          le=1)
    allow_large_dt: bool = _f(False, "accept a step above the safe fraction of the contact "
                              "time")
    skin: Float | None = _f(None, "neighbour-list skin [m]; default 0.2 mean radius", gt=0)
    check_interval: Int = _f(100, "steps between NaN/overlap/stop checks [-]; 1..1e6",
                             ge=1, le=1_000_000)
    overlap_limit: Float = _f(0.2, "stop when an overlap exceeds this fraction of the "
                              "smaller radius [-]; (0, 1]", gt=0, le=1)
    orientations: bool = _f(True, "turn the grains' orientations every step; false "
                            "leaves them as they are (on the CPU; the GPU always turns "
                            "them; they act on nothing, and turning costs about a tenth "
                            "of a step)")

    @field_validator("integrator")
    @classmethod
    def _known(cls, name):
        integrator_id(name)
        return name


def build(state, setup, settings: SoftEngine):
    """The Simulation of ``state`` with ``setup`` (engines.Setup) and ``settings``."""
    return Simulation(state, materials=setup.materials, model=setup.model,
                      walls=setup.walls, periodic=setup.periodic, gravity=setup.gravity,
                      backend=setup.backend, dt=settings.dt, skin=settings.skin,
                      integrator=settings.integrator, allow_large_dt=settings.allow_large_dt,
                      overlap_limit=settings.overlap_limit,
                      check_interval=settings.check_interval,
                      orientations=settings.orientations, symmetry=setup.symmetry)


def check(state, setup, settings: SoftEngine):
    """The time-step report (timestep.time_step_report) of ``state``; ValueError naming
    engine.dt when the step is above the safe fraction of the contact time."""
    try:
        report = time_step_report(state, setup.materials, setup.model, settings.dt,
                                  settings.integrator)
    except (ValueError, ZeroDivisionError) as err:
        raise ValueError(f"cannot work out a time step: {err}") from None
    dt = settings.dt
    if dt is not None and report["fraction"] > report["max_fraction"] \
            and not settings.allow_large_dt:
        raise ValueError(
            f"engine.dt = {dt:.3g} s is {report['fraction']:.2f} of the "
            f"{report['criterion']} {report['critical_time_s']:.3g} s of the smallest grain"
            + (f" ({report['limit']})" if "limit" in report else "") + "; "
            f"allowed: dt <= {report['max_fraction'] * report['critical_time_s']:.3g} s "
            f"(suggested {report['suggested_dt_s']:.3g} s), or set "
            "engine.allow_large_dt = true")
    return report


SOFT = EngineKind("soft", SoftEngine, build, check,
                  "time-driven soft particles: overlapping grains, contact laws, an "
                  "explicit integrator with a fixed time step", symmetry=True,
                  friction_change=True)
