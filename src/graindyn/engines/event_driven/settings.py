"""The event-driven engine's ``[engine]`` settings and its entry in the engine registry
(engines.ENGINES): how a config's grains, walls and materials become an EventDriven
engine.  The contact laws of ``[contact]`` do not apply (hard grains): the materials'
restitution is the normal restitution e_n."""
from typing import Literal

from ...schema import Float, Section, described as _f
from .. import EngineKind
from .collision import COLLAPSE
from .engine import EventDriven


class EventDrivenEngine(Section):
    """Hard grains by event-driven molecular dynamics (Pérez Sec. 2, Eq. 1-10):
    instantaneous binary collisions with normal and tangential restitution, free flight
    on parabolas in between, no time step."""

    kind: Literal["event_driven"] = _f(
        "event_driven", "engine: event_driven (hard grains, collision by collision)")
    tangential_restitution: Float = _f(
        1.0, "e_s of Perez Eq. 6 [-]: +1 smooth, -1 perfectly rough; [-1, 1]", ge=-1, le=1)
    collapse: Literal[tuple(COLLAPSE)] = _f(
        "none", "inelastic collapse treatment: none, speed (e_n -> 1 below collapse_speed) "
                "or tc (elastic within contact_duration of a grain's last collision)")
    collapse_speed: Float | None = _f(None, "u0 of collapse = speed [m/s]; > 0", gt=0)
    contact_duration: Float | None = _f(None, "t_c of collapse = tc [s]; > 0", gt=0)
    tolerance: Float = _f(1e-9, "contact tolerance, fraction of a radius [-]; (0, 1e-3)",
                          gt=0, lt=1e-3)
    sync_interval: Float | None = _f(None, "longest stretch between pauses of a run with "
                                     "a stop condition [s]; default 1/100 of the run",
                                     gt=0)


def build(state, setup, settings: EventDrivenEngine):
    """The EventDriven engine of ``state`` with ``setup`` (engines.Setup) and
    ``settings``; ValueError on the GPU backend (CPU only)."""
    _cpu(setup)
    return EventDriven(state, setup.materials, walls=setup.walls, periodic=setup.periodic,
                       gravity=setup.gravity,
                       tangential_restitution=settings.tangential_restitution,
                       collapse=settings.collapse, collapse_speed=settings.collapse_speed,
                       contact_duration=settings.contact_duration,
                       tolerance=settings.tolerance, sync_interval=settings.sync_interval)


def _cpu(setup):
    if setup.backend != "cpu":
        raise ValueError("the event-driven engine runs on the CPU only: set "
                         "run.backend = 'cpu'")


def check(state, setup, settings: EventDrivenEngine):
    """The time-step report of an engine without a time step (every field says so);
    ValueError on the GPU backend or when the collapse model lacks its parameter."""
    _cpu(setup)
    if settings.collapse == "speed" and settings.collapse_speed is None:
        raise ValueError("engine.collapse = 'speed' needs engine.collapse_speed [m/s]")
    if settings.collapse == "tc" and settings.contact_duration is None:
        raise ValueError("engine.collapse = 'tc' needs engine.contact_duration [s]")
    return {"criterion": "none (event-driven: no time step)", "critical_time_s": None,
            "fraction": None, "max_fraction": None, "suggested_dt_s": None}


EVENT_DRIVEN = EngineKind(
    "event_driven", EventDrivenEngine, build, check,
    "event-driven molecular dynamics: hard spheres and disks, instantaneous collisions "
    "with normal and tangential restitution, analytic free flight, an event calendar",
    ("fixed", "velocity", "sinusoid"), contact_laws=False)
