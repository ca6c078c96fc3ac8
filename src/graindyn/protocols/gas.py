"""The freely cooling granular gas: grains at random in a fully periodic box, given a
Maxwellian velocity distribution of granular temperature T0, left to collide without
gravity; their temperature decays by the inelastic collisions.  Homogeneous cooling
follows Haff's law (analysis.gas.haff_temperature),

    T(t) = T0 / (1 + t / t0)^2,   t0 = 2 d / ((1 - e^2) Gamma0)   (smooth grains),

until clusters form.  The protocol records T(t) (translational and rotational) and the
collisions, fits t0 from sqrt(T0 / T) = 1 + t / t0 and reports the initial collision
rate Gamma0; the same config runs on the event-driven and the soft engine, so that the
two can be compared on one gas (BENCHMARKS.md).
"""
import math
from typing import Literal

import numpy as np

from ..analysis.gas import granular_temperature
from ..core.triggers import Periodic
from ..schema import Float, Section, described as _f
from .base import Protocol, ProtocolPhase, register, run_until, write_rows
from .prepare import maxwellian_velocities


class CoolingGasSettings(Section):
    """A freely cooling gas in the config's box, periodic along every axis."""

    kind: Literal["cooling_gas"] = "cooling_gas"
    temperature: Float = _f(1e-9, "initial granular temperature T0 [J] (kinetic energy "
                            "per degree of freedom); > 0", gt=0)
    duration: Float = _f(1.0, "simulated time of the cooling [s]; (0, 1e6]", gt=0, le=1e6)
    sample_every: Float = _f(1e-2, "time between samples of the temperature [s]; > 0",
                             gt=0)

    def fill_settings(self):
        """Keyword arguments of prepare.fill: random insertion in the whole box."""
        return {"insertion": "random", "packing_fraction": None}


class Thermalise(ProtocolPhase):
    """Give every grain a velocity of the Maxwellian of temperature T0 with zero total
    momentum (prepare.maxwellian_velocities), drawn with the protocol's seed."""

    name = "thermalise"

    def duration(self):
        return 0.0

    def run(self, engine, state, *, every=(), between=None):
        s = engine.state
        rng = np.random.default_rng(self.protocol.seed)
        velocities = maxwellian_velocities(s.masses, self.p.temperature, rng, s.dim)
        engine.relocate(np.arange(s.n), s.positions.copy(), velocities)
        state["report"] = {"temperature_J": self.p.temperature, "grains": s.n}
        return "done"


class Cool(ProtocolPhase):
    """Let the gas cool for ``duration``, sampling T(t) every ``sample_every``."""

    name = "cool"

    def duration(self):
        return self.p.duration

    def run(self, engine, state, *, every=(), between=None):
        rows = state.setdefault("rows", [])
        state.setdefault("start", engine.time)

        def sample(e):
            translational, rotational = granular_temperature(e.state)
            rows.append({"time_s": e.time - state["start"], "temperature_J": translational,
                         "rotational_temperature_J": rotational,
                         "collisions": _collisions(e)})

        if not rows:
            sample(engine)
        status = run_until(engine, state, "end_time", self.p.duration,
                           every=[(Periodic(time=self.p.sample_every), sample), *every],
                           between=between)
        if status == "done":
            state["report"] = cooling_report(rows)
            if self.protocol.folder is not None:
                write_rows(self.protocol.folder / "cooling.csv", rows)
        return status


def _collisions(engine):
    """The engine's collision count, NaN where it counts none (contact dynamics, the
    soft engine on the GPU)."""
    counted = getattr(engine, "collisions", None)
    return math.nan if counted is None else counted


def cooling_report(rows):
    """The cooling's summary from its samples (dicts of time_s, temperature_J,
    collisions): initial and final temperature [J], the Haff time t0 [s] fitted by least
    squares to sqrt(T0/T) - 1 = t/t0 over the samples, the collisions, and the
    collisions per second of the whole gas over the first tenth of the samples."""
    t = np.array([r["time_s"] for r in rows])
    temperature = np.array([r["temperature_J"] for r in rows])
    collisions = np.array([r["collisions"] for r in rows], dtype=float)
    y = np.sqrt(temperature[0] / temperature) - 1.0
    slope = float(t @ y / (t @ t)) if t @ t > 0 else math.nan
    early = max(1, len(rows) // 10)
    return {"initial_temperature_J": float(temperature[0]),
            "final_temperature_J": float(temperature[-1]),
            "haff_time_fitted_s": 1.0 / slope if slope > 0 else math.inf,
            "collisions": float(collisions[-1] - collisions[0]),
            "initial_collisions_per_s": float((collisions[early] - collisions[0])
                                              / (t[early] - t[0])) if len(rows) > 1
            else math.nan}


@register
class CoolingGas(Protocol):
    """The freely cooling granular gas (module docstring)."""

    kind = "cooling_gas"
    settings = CoolingGasSettings
    summary = "a granular gas in a periodic box cooling by its collisions (Haff's law)"

    def __init__(self, settings, vessel):
        super().__init__(settings, vessel)
        self.phases = (Thermalise(self), Cool(self))

    @classmethod
    def cross_check(cls, config):
        box = config.walls.container
        dim = config.run.dim
        if getattr(box, "kind", None) != "box":
            raise ValueError("protocol cooling_gas needs walls.container of kind 'box'")
        spans = {axis: (lo, hi) for axis, lo, hi in config.walls.periodic}
        for axis in range(dim):
            if spans.get(axis) != (box.lo[axis], box.hi[axis]):
                wanted = ", ".join(f"[{a}, {box.lo[a]}, {box.hi[a]}]" for a in range(dim))
                raise ValueError("protocol cooling_gas needs the box periodic along every "
                                 f"axis: give walls.periodic = [{wanted}]")
        if any(config.run.gravity):
            raise ValueError("protocol cooling_gas needs run.gravity = [0, 0, 0]")

    def walls(self, container, material_index):
        """No walls: the box's faces are periodic."""
        return [w for w in container if w.name not in ("xlo", "xhi", "ylo", "yhi", "zlo",
                                                       "zhi")]

    def results(self, engine, states):
        report = dict(states["cool"]["report"])
        report["grains"] = engine.state.n
        report["initial_collision_rate_per_grain"] = \
            2.0 * report["initial_collisions_per_s"] / engine.state.n
        return report

    def figures(self, rundir, series, results):
        """T/T0 against time, log-log, with the fitted Haff law."""
        from ..figures import subplots

        from .deposition import save_figure

        rows = _rows(rundir)
        if len(rows) < 2:
            return []
        t = np.array([r["time_s"] for r in rows])
        temperature = np.array([r["temperature_J"] for r in rows])
        rot = np.array([r["rotational_temperature_J"] for r in rows])
        fig, ax = subplots(figsize=(6, 4.5))
        keep = t > 0
        ax.loglog(t[keep], temperature[keep] / temperature[0], "o", ms=3,
                  label="translational")
        if rot.any():
            ax.loglog(t[keep], rot[keep] / temperature[0], "s", ms=3, label="rotational")
        t0 = results["haff_time_fitted_s"]
        if math.isfinite(t0):
            ax.loglog(t[keep], 1.0 / (1.0 + t[keep] / t0) ** 2, "k-",
                      label=f"Haff, t0 = {t0:.3g} s (fitted)")
        ax.set(xlabel="t [s]", ylabel="T / T0 [-]", title=f"{self.title}: free cooling")
        ax.legend()
        return [save_figure(fig, rundir, "cooling.png")]


def _rows(rundir):
    import csv

    path = rundir.path / "cooling.csv"
    if not path.exists():
        return []
    with path.open() as f:
        return [{k: float(v) for k, v in row.items()} for row in csv.DictReader(f)]
