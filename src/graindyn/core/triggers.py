"""When Python runs between compiled chunks: periodic triggers in steps or simulated
time, and the compiled stop conditions that end a ``run`` early."""
from dataclasses import dataclass

# the compiled stop conditions (the engines' checks read these codes)
NO_CONDITION, MAX_SPEED_BELOW, ENERGY_RATIO_BELOW = 0, 1, 2


@dataclass(frozen=True)
class Periodic:
    """Fires every ``steps`` steps, or every ``time`` seconds of simulated time."""

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
