"""Phases every protocol may reuse: settling under gravity (``Settle``) and holding the
sample as it is for a while (``Hold``), with the settings sections they read."""
import math
from typing import Literal

import numpy as np

from ..analysis.packing import coordination_number, packing_fraction
from ..core.triggers import EnergyRatioBelow, MaxSpeedBelow, Periodic
from ..schema import Float, Section, described as _f
from .base import Phase, run_until

GOLDEN = (math.sqrt(5.0) - 1.0) / 2.0         # the R1 and R2 low-discrepancy sequences
PLASTIC = 1.32471795724474602596
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
    filling: Literal["cloud", "rain"] = _f(
        "cloud", "cloud: every grain released at once from the insertion; rain: the grains "
        "rained in one by one from rain_height at rain_rate, as laboratories fill silos")
    rain_rate: Float = _f(2000.0, "grains per second rained in (filling = rain); > 0",
                          gt=0)
    rain_height: Float | None = _f(None, "height [m] above the floor the grains are "
                                   "released from (filling = rain; default: the top of "
                                   "the container); > 0", gt=0)
    settle_friction: Float | None = _f(
        None, "sliding and static friction coefficient [-] of every material (grains and "
        "walls) while the grains are rained in and settle, the materials' own coming "
        "back for the phases after: 0 (friction off, then on) packs the grains denser, "
        "a large value looser (engine.set_friction); default: the materials' own; >= 0",
        ge=0)

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
    sample's packing fraction, coordination, apparent weight on the bottom, and their
    ``history`` while it settles (Karrech et al.'s Fig. 3: time [s], bottom force over
    the weight, coordination number, packing fraction of the bed between the floor and
    its highest grain), sampled between compiled chunks at most HISTORY_ROWS times.
    With ``settle_friction`` the materials have that friction coefficient while it
    (and a Rain before it) runs, set again whenever the phase starts or resumes, and
    their own from its end on (preparation_friction)."""

    name = "settle"
    HISTORY_ROWS = 400

    def __init__(self, settings: SettleSettings, vessel):
        self.p = settings
        self.vessel = vessel
        self.criterion = EnergyRatioBelow(settings.threshold) \
            if settings.criterion == "energy_ratio" else MaxSpeedBelow(settings.threshold)

    def duration(self):
        return self.p.max_time

    def run(self, engine, state, *, every=(), between=None):
        preparation_friction(engine, self.p, True)
        state.setdefault("end_time", engine.time + self.p.max_time)
        if "armed_time" not in state:
            up = self.vessel.dim - 1
            s = engine.state
            drop = float(np.max(s.positions[:, up] - s.radii)) - self.vessel.floor
            g = float(np.linalg.norm(engine.gravity))
            fall = math.sqrt(2.0 * max(drop, 0.0) / g) if g > 0 else 0.0
            state["armed_time"] = min(state["end_time"], engine.time + fall)
        history = state.setdefault("history", [])
        spacing = self.p.max_time / self.HISTORY_ROWS

        def sample(engine):
            if not history or engine.time >= history[-1]["time_s"] + spacing:
                history.append(self.sample(engine))
            return between is not None and between(engine)
        status = run_until(engine, state, "armed_time", 0.0, every=every, between=sample)
        if status == "done":
            status = run_until(engine, state, "end_time", 0.0, until=self.criterion,
                               every=every, between=sample)
        if status != "stopped":
            state["reached"] = status == "condition"
            history.append(self.sample(engine))
            state["report"] = self.report(engine, state)
            preparation_friction(engine, self.p, False)
        return "stopped" if status == "stopped" else "done"

    def sample(self, engine):
        """One row of the settling history (class docstring)."""
        s, v = engine.state, self.vessel
        up = v.dim - 1
        top = float(np.max(s.positions[:, up] + s.radii))
        weight = float(np.sum(s.masses[s.fixed == 0]) * np.linalg.norm(engine.gravity))
        walls = engine.walls
        floor = v.bottom_wall is not None and weight > 0    # a silo has no floor wall
        return {"time_s": engine.time,
                "apparent_weight_ratio": walls.normal_force(walls.index(v.bottom_wall))
                / weight if floor else math.nan,
                "coordination": coordination_number(engine),
                "packing_fraction": packing_fraction(s, v.cross_section, v.floor, top)
                if top > v.floor else math.nan}

    def report(self, engine, state):
        report = settle_report(engine, state["reached"], self.criterion,
                               self.vessel.bottom_wall, self.vessel.cross_section)
        report["history"] = state["history"]
        return report

    def verdict(self, state):
        """When the criterion was not met: the E_kin/E_pot it ended at and, when a few
        grains hold the energy (analysis.energy.kinetic_holders), which, and how many of
        them slip nowhere (their sliding speeds below a thousandth of their surface
        speeds): grains a law without rolling or twisting resistance never stops."""
        report = state.get("report", {})
        if report.get("reached", True):
            return None
        line = (f"{self.criterion} not met in {self.p.max_time:g} s: E_kin/E_pot = "
                f"{report['energy_ratio']:.3g}, {100 * report['rotational_share']:.0f} % of "
                f"E_kin rotational")
        holders = report.get("kinetic_holders", [])
        if not holders:
            return line
        kinetic = report["energy_J"]["kinetic"] + report["energy_J"]["rotational"]
        held = sum(h["translational_J"] + h["rotational_J"] for h in holders) / kinetic
        rolling = sum(h["slip_m_s"] <= 1e-3 * h["surface_speed_m_s"] for h in holders)
        names = ", ".join(str(h["grain"]) for h in holders)
        if len(holders) == 1:
            line += f"; grain {names} holds {100 * held:.0f} % of it"
            line += " and slips at none of its grain contacts" if rolling else ""
        else:
            line += f"; grains {names} hold {100 * held:.0f} % of it"
            line += (f", {rolling} of them slipping at none of their grain contacts"
                     if rolling else "")
        if rolling:
            line += (": with no rolling or twisting resistance in the contact law "
                     "(contact.rolling, contact.twisting), a grain that rolls, or spins "
                     "about the line of its contacts, keeps its energy")
        return line


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


def preparation_friction(engine, settings: SettleSettings, on):
    """Give the materials settle_friction (``on``) or their own again (not ``on``),
    when settings.settle_friction is set; ValueError for an engine without Coulomb
    friction coefficients to change (engine.set_friction)."""
    if settings.settle_friction is None:
        return
    if not hasattr(engine, "set_friction"):
        raise ValueError("protocol.settle_friction needs an engine whose friction "
                         "coefficients can change during a run (the soft engine)")
    engine.set_friction(settings.settle_friction if on else None)


def preparation(settings: SettleSettings, vessel):
    """The phases that make a settled sample: Settle, after Rain when the grains are
    rained in."""
    settle = Settle(settings, vessel)
    return (Rain(settings, vessel), settle) if settings.filling == "rain" else (settle,)


class Rain(Phase):
    """Gentle filling: every grain is first held in a reservoir above the container
    (Engine.hold), then released one by one at ``rain_rate`` grains per second from
    ``rain_height`` above the floor, at rest, at places spread over the container's
    cross-section by a low-discrepancy sequence (R1 in 2D, R2 in 3D: Roberts 2018), a
    place being skipped while a grain released before is still there; the phase ends
    when every grain is released (the count sets the fill height) and the Settle that
    follows lets the last ones land.  Unlike a cloud dropped at once, which lands as a
    block and can lock wall friction downward, each grain arrives alone on the pile."""

    name = "rain"

    def __init__(self, settings: SettleSettings, vessel):
        self.p = settings
        self.vessel = vessel

    def duration(self):
        return self.p.max_time

    def _places(self, k):
        """The k-th place (x, y) of the sequence in the container's cross-section."""
        v = self.vessel
        if v.dim == 2:
            return np.array([(0.5 + GOLDEN * k) % 1.0])
        return np.array([(0.5 + k / PLASTIC) % 1.0, (0.5 + k / PLASTIC**2) % 1.0])

    def _place(self, k, radius):
        """Grain position [m] of sequence point k, or None outside a cylinder."""
        v = self.vessel
        up = v.dim - 1
        u = self._places(k)
        lo, hi = np.array(v.lo[:up]) + radius, np.array(v.hi[:up]) - radius
        point = np.zeros(3)
        point[:up] = lo + u * (hi - lo)
        if v.shape == "cylinder" and np.hypot(*(point[:2] - v.center)) > v.radius - radius:
            return None
        height = self.p.rain_height if self.p.rain_height is not None else v.top - v.floor
        point[up] = v.floor + height - radius
        return point

    def run(self, engine, state, *, every=(), between=None):
        preparation_friction(engine, self.p, True)
        s = engine.state
        up = self.vessel.dim - 1
        if "released" not in state:
            gap = 2.2 * float(s.radii.max())
            lo, hi = np.array(self.vessel.lo[:up]), np.array(self.vessel.hi[:up])
            per_axis = np.maximum(1, ((hi - lo) // gap).astype(int))
            cells = int(np.prod(per_axis))
            k = np.arange(s.n)
            reservoir = np.zeros((s.n, 3))
            layer, cell = np.divmod(k, cells)
            index = np.array(np.unravel_index(cell, per_axis)).T
            reservoir[:, :up] = lo + (index + 0.5) * gap
            reservoir[:, up] = self.vessel.top + 10.0 * gap + layer * gap
            engine.relocate(k, reservoir, np.zeros((s.n, 3)))
            engine.hold(k)
            state.update(released=0, place=0, start=engine.time,
                         end_time=engine.time + self.p.max_time)
        interval = max(1.0 / self.p.rain_rate, 1e-4)

        def rain(engine):
            due = min(s.n, int((engine.time - state["start"]) * self.p.rain_rate) + 1)
            tries = 0
            while state["released"] < due and tries < 64:
                i = state["released"]
                point = self._place(state["place"], s.radii[i])
                state["place"] += 1
                tries += 1
                if point is None or self._occupied(s, point, s.radii[i]):
                    continue
                engine.release([i], point[None, :], np.zeros((1, 3)))
                state["released"] += 1
                tries = 0

        interrupted = []

        def pause(engine):
            if between is not None and between(engine):
                interrupted.append(True)
                return True
            return state["released"] >= s.n

        run_until(engine, state, "end_time", 0.0,
                  every=[*every, (Periodic(time=interval), rain)], between=pause)
        if interrupted:
            return "stopped"
        if state["released"] < s.n:
            raise ValueError(f"rain: {state['released']} of {s.n} grains released in "
                             f"max_time = {self.p.max_time} s: raise rain_rate or max_time")
        return "done"

    @staticmethod
    def _occupied(s, point, radius):
        """True when a free grain overlaps a grain of ``radius`` at ``point``."""
        free = s.fixed == 0
        d2 = np.sum((s.positions[free] - point) ** 2, axis=1)
        return bool(np.any(d2 < (s.radii[free] + radius) ** 2))
