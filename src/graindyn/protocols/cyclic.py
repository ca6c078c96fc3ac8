"""Cyclic loading of a confined granular bed through a rigid top plate (Karrech et al.,
Sec. 2 and 5, Fig. 2): the molecular-dynamics part of their long-term settlement study.

Phases: "settle" (grains spread at random in the container, settled under gravity until
E_kin/E_pot <= threshold, Karrech Sec. 3) and "cycles": the plate, a plane over the
whole top of the sample, is put just above the highest grain and becomes a piston
(core.walls, piston motion) of mass ``plate_mass`` under gravity, pushed down by the
stress signal

    sigma(t) = static_stress + (stress_amplitude / 2) (1 - cos(2 pi f (t - t_0))),

t_0 the start of the cycles.  Karrech et al. describe the load only as "a sinusoidal law"
of amplitude Delta sigma (their Fig. 2); this is our reading of it: a haversine between
the static stress and static + Delta sigma, the shape of a passing axle, zero at each
cycle's end, so that the state at the end of a cycle is the unloaded (residual) one the
paper measures.  The plate's weight M g adds to the applied force.

At the end of each cycle the phase records the settlement (how far the plate has gone
down since the cycles started), the plate and bottom stresses, the mean lateral stress,
the coordination number, the packing fraction below the plate and the kinetic energy
(``rows``), and the residual displacement of every grain since the cycles started,
u_beta(p) = r_beta(t_0 + p T) - r_beta(t_0), written to residuals/cycle_NNNNNN.npy in
the run directory (``load_residuals`` reads them back as one (cycles, N, 3) array, the
training data of analysis.settlement).

Only the fully confined mode (the plate over the whole surface) is built; the partially
confined mode (a plate over 80 % of the width) and the quarter model with symmetry
planes are not.
"""
import pathlib
from typing import Literal

import numpy as np
from ..analysis.packing import coordination_number
from ..analysis.energy import energy_budget
from ..core.walls import Motion, Plane
from ..schema import Float, Int, described as _f
from .base import Protocol, ProtocolPhase, lower_onto_grains, register, run_until, write_rows
from .deposition import save_figure
from .phases import SettleSettings, preparation

PLATE = "plate"
PARK = 100.0


class CyclicSettings(SettleSettings):
    """Settle, then load the bed cyclically through a rigid top plate (Karrech et al.):
    the stress on the plate a haversine of ``stress_amplitude`` at ``frequency`` above
    ``static_stress`` (module docstring), ``cycles`` cycles."""

    kind: Literal["cyclic"] = "cyclic"
    stress_amplitude: Float = _f(14.15e3, "Delta sigma [Pa]: the stress on the plate goes "
                                 "from static_stress to static_stress + Delta sigma and "
                                 "back each cycle; > 0", gt=0)
    static_stress: Float = _f(0.0, "stress [Pa] held on the plate under the cycles (its "
                              "weight comes on top); >= 0", ge=0)
    frequency: Float = _f(50.0, "loading frequency f [Hz]; > 0", gt=0)
    cycles: Int = _f(10, "loading cycles [-]; >= 1", ge=1)
    plate_mass: Float | None = _f(None, "mass of the plate [kg]; default: the mass of the "
                                  "grains; > 0", gt=0)
    plate_material: str | None = _f(None, "plate material; default: walls.material")
    residuals: bool = _f(True, "write every grain's residual displacement at each cycle "
                         "end (residuals/cycle_NNNNNN.npy)")


@register
class Cyclic(Protocol):
    """Cyclic loading of a settled bed through a rigid plate (Karrech et al.)."""

    kind = "cyclic"
    settings = CyclicSettings
    summary = ("settle, then load the bed cyclically through a rigid plate and record the "
               "settlement and residual displacements per cycle (Karrech et al.)")

    def __init__(self, settings, vessel):
        super().__init__(settings, vessel)
        self.phases = (*preparation(settings, vessel), Cycles(self))

    @classmethod
    def cross_check(cls, config):
        settings = config.protocol
        settings.check_dim(config.run.dim)
        box = config.walls.container
        if getattr(box, "kind", None) == "box" and not box.open_top:
            raise ValueError("the cyclic protocol needs a cylinder or an open-top box (the "
                             "plate closes it)")

    @classmethod
    def materials_named(cls, settings):
        return [("protocol.plate_material", settings.plate_material)] \
            if settings.plate_material is not None else []

    def walls(self, container, material_index):
        """The container and the plate: a plane facing down, parked PARK container
        heights above the floor (out of the way of a dilute cloud of grains: a solid
        fraction of 0.05 settles to about a tenth of its height) until the cycles put it
        on the bed."""
        v = self.vessel
        material = material_index(self.p.plate_material)
        park = v.floor + PARK * (v.top - v.floor)
        if v.dim == 2:
            point, normal = (0.5 * (v.lo[0] + v.hi[0]), park, 0.0), (0.0, -1.0, 0.0)
        else:
            center = v.center if v.center is not None \
                else tuple(0.5 * (np.asarray(v.lo[:2]) + v.hi[:2]))
            point, normal = (*center, park), (0.0, 0.0, -1.0)
        return list(container) + [Plane(point, normal, material, name=PLATE,
                                        area=v.cross_section)]

    def results(self, engine, states):
        out = {"deposition": states["settle"]["report"], "cycles": states["cycles"]["rows"],
               "signal": "sigma(t) = static + amplitude (1 - cos(2 pi f (t - t0))) / 2"}
        rows = out["cycles"]
        if rows:
            out["settlement_m"] = rows[-1]["settlement_m"]
        return out

    def tables(self, rundir, results):
        """cycles.csv: one row per cycle."""
        return [write_rows(rundir.path / "cycles.csv", results["cycles"])]

    def figures(self, rundir, series, results):
        """Settlement and coordination against the cycle number, and the plate stress
        against time."""
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        rows = results["cycles"]
        fig, ax = plt.subplots(1, 3, figsize=(15, 4.2))
        n = [r["cycle"] for r in rows]
        ax[0].plot(n, [1e3 * r["settlement_m"] for r in rows], "o-")
        ax[0].set(xlabel="cycle", ylabel="settlement [mm]")
        ax[1].plot(n, [r["coordination"] for r in rows], "o-")
        ax[1].set(xlabel="cycle", ylabel="coordination number [-]")
        t = series["time [s]"]
        ax[2].plot(t, series[f"force_{PLATE} [N]"] / self.vessel.cross_section / 1e3)
        ax[2].set(xlabel="t [s]", ylabel="plate stress [kPa]")
        fig.suptitle(f"{self.title}: {len(rows)} load cycles, "
                     f"{results['deposition'].get('grains', '?')} grains")
        return [save_figure(fig, rundir, "cyclic.png")]


class Cycles(ProtocolPhase):
    """The plate put on the bed, then ``cycles`` load cycles (module docstring)."""

    name = "cycles"

    def duration(self):
        return self.p.cycles / self.p.frequency

    def run(self, engine, state, *, every=(), between=None):
        p, v = self.p, self.vessel
        k = engine.walls.index(PLATE)
        up = v.dim - 1                                  # the vertical axis
        if "start_s" not in state:
            s = engine.state
            lower_onto_grains(engine, k)
            mass = p.plate_mass if p.plate_mass is not None else float(np.sum(s.masses))
            weight = mass * float(np.linalg.norm(engine.gravity))
            half = 0.5 * p.stress_amplitude * v.cross_section
            direction = [0.0, 0.0, 0.0]
            direction[up] = -1.0
            engine.set_motion(k, Motion(
                "piston", direction=tuple(direction), mass=mass,
                force=p.static_stress * v.cross_section + weight + half,
                force_amplitude=half, frequency=p.frequency, phase=-0.5 * np.pi,
                start=engine.time))
            state.update(start_s=engine.time, plate_0=self._plate(engine, k), rows=[],
                         reference=s.positions.tolist())
        while len(state["rows"]) < p.cycles:
            outcome = run_until(engine, state, "cycle_end", 1.0 / p.frequency, every=every,
                                between=between)
            if outcome == "stopped":
                return "stopped"
            self._record(engine, state, k)
            del state["cycle_end"]
        engine.set_motion(k, Motion("fixed"))
        return "done"

    def _plate(self, engine, k):
        """Height [m] of the plate."""
        up = self.vessel.dim - 1
        return float(engine.walls.geometry[k, up] + engine.walls.offset[k, up])

    def _record(self, engine, state, k):
        """The row of the cycle that ends now, and its residual displacements."""
        v, s = self.vessel, engine.state
        walls = engine.walls
        cycle = len(state["rows"]) + 1
        residual = s.positions - np.asarray(state["reference"])
        plate = self._plate(engine, k)
        height = plate - v.floor
        solid = float(np.sum(np.pi * s.radii**2)) if v.dim == 2 \
            else float(np.sum(4.0 / 3.0 * np.pi * s.radii**3))
        sides = [walls.index(n) for n in v.side_walls]
        contacts = engine.wall_contacts()
        lateral = float(np.sum(contacts.normal_force[np.isin(contacts.wall, sides)])) \
            / (v.perimeter * height)
        e = energy_budget(engine)
        row = {"cycle": cycle, "time_s": engine.time,
               "settlement_m": state["plate_0"] - plate, "plate_height_m": plate,
               "sigma_plate_Pa": walls.normal_force(k) / v.cross_section,
               "sigma_bottom_Pa": walls.normal_force(walls.index(v.bottom_wall))
               / v.cross_section, "sigma_lateral_Pa": lateral,
               "packing_fraction": solid / (v.cross_section * height),
               "coordination": coordination_number(engine),
               "mean_residual_m": float(np.mean(np.linalg.norm(residual, axis=1))),
               "kinetic_J": e["kinetic"] + e["rotational"]}
        state["rows"].append(row)
        if self.p.residuals and self.protocol.folder is not None:
            folder = pathlib.Path(self.protocol.folder) / "residuals"
            folder.mkdir(exist_ok=True)
            np.save(folder / f"cycle_{cycle:06d}.npy", residual)
        self.protocol.log(f"cycle {cycle}: settlement {1e3 * row['settlement_m']:.4g} mm, "
                          f"coordination {row['coordination']:.3f}")


def load_residuals(run_dir):
    """The residual displacements of a cyclic run, (cycles, N, 3) [m], cycle 1 first, from
    its residuals/ folder."""
    files = sorted((pathlib.Path(run_dir) / "residuals").glob("cycle_*.npy"))
    if not files:
        raise FileNotFoundError(f"{run_dir}: no residuals/cycle_*.npy")
    return np.stack([np.load(f) for f in files])
