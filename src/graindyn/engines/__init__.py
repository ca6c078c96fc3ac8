"""The engines: each a way of moving grains behind the interface of core.engine.Engine.

``ENGINES`` is the one registry of them, read by config validation (the ``[engine]``
section is the settings class of its ``kind``), by config.build (which builds the engine
of a run) and by ``graindyn info``.  An engine joins it with ``register``: its kind, the
Section of its settings and the functions that check and build it.
"""
from dataclasses import dataclass
from typing import Callable, NamedTuple

from ..schema import Section


class Setup(NamedTuple):
    """What every engine is built from besides the grains (core.state.State):
    materials (core.species.Material list, indexed by material id), model (the contact
    laws, core.species.ContactModel), walls (core.walls Plane/Cylinder/... list), periodic
    (core.walls.Periodic list), gravity (3,) [m/s^2], backend ("cpu" or "gpu"),
    symmetry (core.symmetry.Symmetry planes: only for an engine whose entry says it
    has them, EngineKind.symmetry)."""

    materials: list
    model: object
    walls: list
    periodic: list
    gravity: tuple
    backend: str
    symmetry: tuple = ()


@dataclass(frozen=True)
class EngineKind:
    """One engine of the registry.

    kind : the name a config gives in engine.kind.
    settings : the Section class of its ``[engine]`` settings (its ``kind`` field a
      Literal of ``kind``).
    build : build(state, setup, settings) -> the engine (core.engine.Engine).
    check : check(state, setup, settings) -> dict, the time-step report of a state of
      the smallest grain (keys criterion, critical_time_s, fraction, max_fraction,
      suggested_dt_s), ValueError when the settings cannot run.
    summary : one line for ``graindyn info``.
    wall_motions : the wall motions (core.walls.Motion kinds) it can run; config
      validation refuses a protocol or a wall that needs another.
    contact_laws : whether it reads the ``[contact]`` laws (checked against the
      materials before a run only then).
    symmetry : whether it runs symmetry planes (core/symmetry.py); config validation
      refuses them for an engine that does not.
    friction_change : whether its friction coefficients can change during a run
      (``set_friction``); config validation refuses protocol.settle_friction otherwise.
    """

    kind: str
    settings: type[Section]
    build: Callable
    check: Callable
    summary: str
    wall_motions: tuple = ("fixed", "velocity", "sinusoid", "servo", "piston")
    contact_laws: bool = True
    symmetry: bool = False
    friction_change: bool = False


ENGINES: dict[str, EngineKind] = {}


def register(entry: EngineKind):
    """Add an engine to ENGINES (its kind must be new); returns it."""
    if entry.kind in ENGINES:
        raise ValueError(f"engine kind {entry.kind!r} is registered already")
    ENGINES[entry.kind] = entry
    return entry


def settings_classes():
    """kind -> settings Section class, for config validation."""
    return {kind: entry.settings for kind, entry in ENGINES.items()}


from .soft.settings import SOFT  # noqa: E402  (registers the soft engine)

register(SOFT)

from .contact_dynamics.settings import CONTACT_DYNAMICS  # noqa: E402

register(CONTACT_DYNAMICS)

from .event_driven.settings import EVENT_DRIVEN  # noqa: E402

register(EVENT_DRIVEN)
