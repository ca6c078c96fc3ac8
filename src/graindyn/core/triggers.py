"""When Python runs between an engine's compiled stretches: triggers that fire every N
steps or every T of simulated time, composable (``a & b``, ``a | b``, ``After``,
``Before``) as HOOMD-blue's triggers are; and the stop conditions that end a ``run``
early.

An engine pauses where some ``Periodic`` of its triggers falls (``Trigger.periodics``)
and there asks each trigger whether it fires (``Trigger.fires``), saying which of the
periodics are due; so a composite trigger fires only at the instants of its periodics.
"""
from dataclasses import dataclass

# the compiled stop conditions (the engines' checks read these codes)
NO_CONDITION, MAX_SPEED_BELOW, ENERGY_RATIO_BELOW = 0, 1, 2


class Trigger:
    """Something that fires at some of an engine's pauses; ``a & b`` fires when both
    do, ``a | b`` when either does."""

    def periodics(self):
        """The Periodic triggers whose instants the engine must pause at."""
        raise NotImplementedError

    def fires(self, due, time):
        """True when the trigger fires at this pause: ``due(periodic)`` says whether a
        Periodic of ``periodics()`` falls now, ``time`` [s] is the simulated time."""
        raise NotImplementedError

    def __and__(self, other):
        return All((self, other))

    def __or__(self, other):
        return Any((self, other))


@dataclass(frozen=True)
class Periodic(Trigger):
    """Fires every ``steps`` steps, or every ``time`` seconds of simulated time (a
    time-stepping engine: every round(time/dt) steps)."""

    steps: int | None = None
    time: float | None = None

    def __post_init__(self):
        if (self.steps is None) == (self.time is None):
            raise ValueError("Periodic needs exactly one of steps= or time=")
        if self.steps is not None and self.steps < 1:
            raise ValueError(f"Periodic steps must be >= 1, got {self.steps}")
        if self.time is not None and not self.time > 0:
            raise ValueError(f"Periodic time must be > 0 [s], got {self.time}")

    def period(self, dt):
        """Period in steps for the time step dt [s]."""
        return self.steps if self.steps is not None else max(1, round(self.time / dt))

    def periodics(self):
        return (self,)

    def fires(self, due, time):
        return due(self)


@dataclass(frozen=True)
class After(Trigger):
    """Fires at every pause from simulated time ``time`` [s] on (combine it with a
    Periodic: ``Periodic(time=1e-3) & After(0.5)``)."""

    time: float

    def periodics(self):
        return ()

    def fires(self, due, time):
        return time >= self.time


@dataclass(frozen=True)
class Before(Trigger):
    """Fires at every pause before simulated time ``time`` [s]."""

    time: float

    def periodics(self):
        return ()

    def fires(self, due, time):
        return time < self.time


@dataclass(frozen=True)
class All(Trigger):
    """Fires when every one of ``triggers`` does."""

    triggers: tuple

    def periodics(self):
        return tuple(p for t in self.triggers for p in t.periodics())

    def fires(self, due, time):
        return all(t.fires(due, time) for t in self.triggers)


@dataclass(frozen=True)
class Any(Trigger):
    """Fires when one of ``triggers`` does."""

    triggers: tuple

    def periodics(self):
        return tuple(p for t in self.triggers for p in t.periodics())

    def fires(self, due, time):
        return any(t.fires(due, time) for t in self.triggers)


def pauses(trigger):
    """The periodics of ``trigger``; TypeError when it is no Trigger or has none (it
    would never be asked)."""
    if not isinstance(trigger, Trigger):
        raise TypeError(f"every= takes (trigger, callback) pairs, got {trigger!r}")
    found = trigger.periodics()
    if not found:
        raise TypeError(f"{trigger!r} has no Periodic: combine it with one, e.g. "
                        "Periodic(time=1e-3) & After(0.5)")
    return found


@dataclass(frozen=True)
class MaxSpeedBelow:
    """Stop when the largest grain speed falls below ``speed`` [m/s]."""

    speed: float
    kind = MAX_SPEED_BELOW

    @property
    def value(self):
        return self.speed


@dataclass(frozen=True)
class EnergyRatioBelow:
    """Stop when kinetic / potential energy <= ``ratio`` (Karrech et al. Sec. 3: E_c/E_p
    <= epsilon, about 1e-6).  E_p is the gravitational energy above the lowest grain."""

    ratio: float
    kind = ENERGY_RATIO_BELOW

    @property
    def value(self):
        return self.ratio
