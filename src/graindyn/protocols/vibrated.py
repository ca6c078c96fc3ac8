"""The vibrated bed: grains settled in the container, then its floor shaken vertically,
z_floor(t) = A (1 - cos 2 pi f t) above its rest place (it starts at rest: a floor
that started at speed 2 pi f A under a bed of touching hard grains would need
infinitely many collisions at that instant), the classic driven granular gas (or, at small
Gamma = A (2 pi f)^2 / g, a bed that compacts).  The protocol records, every
``sample_every``, the height of the grains' centre of mass above the floor's rest place,
their granular temperature and the mean force on the floor, and reports their means
over the second half of the shaking with the dimensionless acceleration Gamma and the
packing-fraction profile at the end."""
import math
from typing import Literal

import numpy as np

from ..analysis.gas import granular_temperature
from ..core.triggers import Periodic
from ..core.walls import Motion
from ..schema import Float, described as _f
from .base import Protocol, ProtocolPhase, register, run_until, write_rows
from .phases import SettleSettings, preparation


class VibratedBedSettings(SettleSettings):
    """Settle the grains, then shake the floor vertically."""

    kind: Literal["vibrated_bed"] = "vibrated_bed"
    amplitude: Float = _f(1e-3, "floor amplitude A [m]; > 0", gt=0)
    frequency: Float = _f(30.0, "floor frequency f [Hz]; > 0", gt=0)
    duration: Float = _f(1.0, "time shaken [s]; (0, 1e4]", gt=0, le=1e4)
    sample_every: Float = _f(1e-3, "time between samples [s]; > 0", gt=0)
    settle_first: bool = _f(True, "settle the grains before shaking; false: shake from "
                            "the inserted cloud")


class Shake(ProtocolPhase):
    """The floor follows A (1 - cos 2 pi f t) from the end of settling for ``duration``."""

    name = "shake"

    def duration(self):
        return self.p.duration

    def run(self, engine, state, *, every=(), between=None):
        floor = self.vessel.bottom_wall
        up = self.vessel.dim - 1
        k = engine.walls.index(floor)
        if "start" not in state:
            state["start"] = engine.time
            state["floor_rest"] = float(engine.walls.geometry[k, up]
                                        + engine.walls.offset[k, up])
            direction = np.zeros(3)
            direction[up] = 1.0
            engine.set_motion(floor, Motion("sinusoid", direction=tuple(direction),
                                            amplitude=self.p.amplitude,
                                            frequency=self.p.frequency,
                                            phase=-0.5 * math.pi))
        rows = state.setdefault("rows", [])

        def sample(e):
            s = e.state
            free = s.fixed == 0
            m = s.masses[free]
            height = float(m @ s.positions[free, up] / m.sum()) - state["floor_rest"]
            rows.append({"time_s": e.time - state["start"], "centre_height_m": height,
                         "temperature_J": granular_temperature(s)[0],
                         "floor_force_N": e.walls.normal_force(k)})

        status = run_until(engine, state, "end_time", self.p.duration,
                           every=[(Periodic(time=self.p.sample_every), sample), *every],
                           between=between)
        if status == "done":
            engine.set_motion(floor, Motion("fixed"))
            state["report"] = self.summary(engine, state)
            if self.protocol.folder is not None and rows:
                write_rows(self.protocol.folder / "vibration.csv", rows)
        return status

    def summary(self, engine, state):
        rows = state["rows"]
        half = [r for r in rows if r["time_s"] >= 0.5 * self.p.duration] or rows
        g = float(np.linalg.norm(engine.gravity))
        s = engine.state
        up = self.vessel.dim - 1
        height = s.positions[:, up] - state["floor_rest"]
        edges = np.linspace(0.0, max(float(height.max() + s.radii.max()), 1e-12), 21)
        solid = 4.0 / 3.0 * math.pi * s.radii**3 if s.dim == 3 else math.pi * s.radii**2
        profile = np.histogram(height, bins=edges, weights=solid)[0] / (
            np.diff(edges) * self.vessel.cross_section)
        return {"gamma": self.p.amplitude * (2 * math.pi * self.p.frequency) ** 2 / g
                if g > 0 else math.inf,
                "mean_centre_height_m": float(np.mean([r["centre_height_m"] for r in half])),
                "mean_temperature_J": float(np.mean([r["temperature_J"] for r in half])),
                "mean_floor_force_N": float(np.mean([r["floor_force_N"] for r in half])),
                "weight_N": float(s.masses[s.fixed == 0].sum() * g),
                "profile_heights_m": (0.5 * (edges[1:] + edges[:-1])).tolist(),
                "profile_packing_fraction": profile.tolist()}


@register
class VibratedBed(Protocol):
    """The vibrated bed (module docstring)."""

    kind = "vibrated_bed"
    settings = VibratedBedSettings
    summary = "settle the grains, shake the floor vertically, record height and temperature"

    def __init__(self, settings, vessel):
        super().__init__(settings, vessel)
        first = preparation(settings, vessel) if settings.settle_first else ()
        self.phases = (*first, Shake(self))

    @classmethod
    def wall_motions(cls, settings):
        """The floor is a sinusoid."""
        return {"sinusoid"}

    @classmethod
    def cross_check(cls, config):
        config.protocol.check_dim(config.run.dim)
        if not any(config.run.gravity):
            raise ValueError("protocol vibrated_bed needs gravity (run.gravity)")

    def results(self, engine, states):
        settled = {"settle": states["settle"]["report"]} if "settle" in states else {}
        return {**settled, **states["shake"]["report"]}

    def figures(self, rundir, series, results):
        """The centre-of-mass height and the temperature against time, and the packing
        profile at the end."""
        import csv

        from ..figures import subplots

        from .deposition import save_figure

        path = rundir.path / "vibration.csv"
        if not path.exists():
            return []
        with path.open() as f:
            rows = [{k: float(v) for k, v in row.items()} for row in csv.DictReader(f)]
        t = np.array([r["time_s"] for r in rows])
        fig, ax = subplots(1, 3, figsize=(13, 4))
        ax[0].plot(t, [1e3 * r["centre_height_m"] for r in rows])
        ax[0].set(xlabel="t [s]", ylabel="centre of mass above the floor [mm]")
        ax[1].semilogy(t, [r["temperature_J"] for r in rows])
        ax[1].set(xlabel="t [s]", ylabel="granular temperature [J]")
        ax[2].plot(results["profile_packing_fraction"],
                   1e3 * np.array(results["profile_heights_m"]), "o-")
        ax[2].set(xlabel="packing fraction [-]", ylabel="height [mm]")
        fig.suptitle(f"{self.title}: Gamma = {results['gamma']:.2f}")
        return [save_figure(fig, rundir, "vibration.png")]
