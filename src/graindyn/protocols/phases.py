"""Phases every protocol may reuse: settling under gravity (``Settle``) and holding the
sample as it is for a while (``Hold``), with the settings sections they read."""
import math
from typing import Literal

import numpy as np

from ..core.triggers import EnergyRatioBelow, MaxSpeedBelow
from ..schema import Float, Section, described as _f
from .base import Phase, run_until
from .prepare import settle_report

# random sequential insertion jams at these solid fractions (Torquato, Random
# Heterogeneous Materials, 2002): no random insertion can reach them
RSA_JAMMING = {2: 0.547, 3: 0.3841}


class SettleSettings(Section):
    """How grains are inserted into the container and settled under gravity: the first
    phase of every protocol that starts from a cloud of grains."""

    insertion: Literal["random", "lattice"] = _f(
        "random", "random non-overlapping insertion, or a loose lattice with random "
        "velocities (Perez)")
    packing_fraction: Float = _f(0.2, "solid fraction of the insertion region [-] (random "
                                 "insertion); (0, RSA jamming: 0.384 in 3D, 0.547 in 2D)",
                                 gt=0, lt=0.547)
    lattice_gap: Float = _f(0.05, "gap between lattice sites [fraction of d_max]; [0, 10]",
                            ge=0, le=10)
    lattice_speed: Float = _f(0.0, "random initial speed on the lattice [m/s]; >= 0", ge=0)
    criterion: Literal["energy_ratio", "max_speed"] = _f(
        "energy_ratio", "equilibrium: E_kin/E_pot <= threshold (Karrech et al.) or the "
        "largest speed below threshold [m/s]")
    threshold: Float = _f(1e-6, "value of the equilibrium criterion; > 0", gt=0)
    max_time: Float = _f(1.0, "longest settling time [s] of simulated time; (0, 1e4]",
                         gt=0, le=1e4)

    def fill_settings(self):
        """Keyword arguments of prepare.fill."""
        return {"insertion": self.insertion, "packing_fraction": self.packing_fraction,
                "lattice_gap": self.lattice_gap, "lattice_speed": self.lattice_speed}

    def check_dim(self, dim):
        """ValueError when random insertion cannot reach packing_fraction in ``dim``D."""
        phi = self.packing_fraction
        if self.insertion == "random" and phi >= RSA_JAMMING[dim]:
            raise ValueError(f"protocol.packing_fraction = {phi}: random insertion cannot "
                             f"reach the RSA jamming fraction {RSA_JAMMING[dim]} in {dim}D; "
                             "use a smaller value (0.2 is quick)")


class Settle(Phase):
    """Settle the grains under gravity until the equilibrium criterion holds (Karrech et
    al. Sec. 3: E_kin/E_pot <= epsilon; or the largest speed below a threshold) or
    ``max_time`` passes.  The criterion is armed only after the free-fall time
    sqrt(2 h / g) of the highest grain above the floor: grains released at rest have
    E_kin/E_pot ~ 0 before they start to fall.  Its report (prepare.settle_report): the
    sample's packing fraction, coordination, apparent weight on the bottom."""

    name = "settle"

    def __init__(self, settings: SettleSettings, vessel):
        self.p = settings
        self.vessel = vessel
        self.criterion = EnergyRatioBelow(settings.threshold) \
            if settings.criterion == "energy_ratio" else MaxSpeedBelow(settings.threshold)

    def duration(self):
        return self.p.max_time

    def run(self, engine, state, *, every=(), between=None):
        state.setdefault("end_time", engine.time + self.p.max_time)
        if "armed_time" not in state:
            up = self.vessel.dim - 1
            s = engine.state
            drop = float(np.max(s.positions[:, up] - s.radii)) - self.vessel.floor
            g = float(np.linalg.norm(engine.gravity))
            fall = math.sqrt(2.0 * max(drop, 0.0) / g) if g > 0 else 0.0
            state["armed_time"] = min(state["end_time"], engine.time + fall)
        status = run_until(engine, state, "armed_time", 0.0, every=every, between=between)
        if status == "done":
            status = run_until(engine, state, "end_time", 0.0, until=self.criterion,
                               every=every, between=between)
        if status != "stopped":
            state["reached"] = status == "condition"
            state["report"] = self.report(engine, state)
        return "stopped" if status == "stopped" else "done"

    def report(self, engine, state):
        return settle_report(engine, state["reached"], self.criterion,
                             self.vessel.bottom_wall, self.vessel.cross_section)


class Hold(Phase):
    """Keep running for ``time`` [s] of simulated time with everything as it is (walls,
    servos, gravity): the sample relaxes, creeps or flows as it will."""

    name = "hold"

    def __init__(self, time):
        if not time >= 0:
            raise ValueError(f"hold time must be >= 0 [s], got {time}")
        self.time = float(time)

    def duration(self):
        return self.time

    def run(self, engine, state, *, every=(), between=None):
        return run_until(engine, state, "end_time", self.time, every=every, between=between)
