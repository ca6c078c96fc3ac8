"""The oedometric test of Oquendo et al. (Sec. 4) and the fit of Bauer's law (Eq. 19).

Phases: "settle" (the deposition protocol: grains inserted at random in the container,
settled under gravity) and "load": the piston, a plane above the sample, is put just
over the highest grain and becomes a stress-controlled wall with target force p A for
the levels p = p0, factor p0, ... up to p_max, and back down when ``unload`` is set.
``loading`` chooses how the piston is driven: "servo" (core.walls, servo motion: a
velocity servo without inertia, below) or "piston" (core.walls, piston motion: a rigid
plate of mass ``piston_mass`` driven by the constant force p A and by the grains, as
Oquendo et al. write that "the top wall falls down with the initial pressure p0"; the
default mass is that of the sample, so that the plate rings on the sample near the
sample's own lowest mode instead of far above it, light, or far below, heavy and slow to
settle).  At each level the sample relaxes until it is at rest:

    |F_piston - p A| <= force_tolerance p A,
    |F_bottom + F_side friction - F_piston - weight| <= force_tolerance p A   and
    E_kin + E_rot <= rest_ratio E_elastic,

(rigid grains, engine.Engine.rigid, store no elastic energy: for them the reference is
p A R_mean, the work of the load over one mean radius), checked between compiled chunks (at most servo_time/4 apart), or until level_max_time
passes (the level is then recorded with at_rest = false).

Servo control law: v = clamp(g (p A - F_piston), -v_max, v_max) along the piston normal,
with the gain re-set between chunks to g = min(v_max/(0.1 p A), 1/(tau K)).  K [N/m] is
the stiffness of the sample seen by the piston: the secant dF/dz of the piston since the
last chunk, capped by the tangent stiffness of the piston's contacts (sum of
1.5 F_c/delta_c, Hertz), which the sample behind them cannot exceed.  So where the
sample responds elastically the force error decays no faster than exp(-t/tau), and
tau >> the sample's wave transit time keeps the loading quasi-static; the wall has no
inertia and cannot overshoot by itself.  Where the sample yields (dF/dz <= 0) or far from
the target (error > 10 %) the piston moves at up to v_max; a sample that creeps at speed
u leaves a force error of 0.1 p A u/v_max until it stops creeping.  On rigid grains the
gain stays at its bound v_max/(0.1 p A): an engine of rigid grains solves the servo's
velocity with the contact impulses (contact dynamics), so it cannot overshoot, and a
secant stiffness of rigid contacts means nothing.

Recorded at each level (``rows``): the stresses on the piston and on the bottom, the
mean lateral stress on the side walls (normal contact forces over the wetted side
area), K0 = lateral / mean vertical stress, the void ratio e = (V - V_s)/V_s from the
piston height (V_s: sum of grain volumes, overlaps neglected), the force the side walls
carry by friction (Janssen), coordination number and kinetic energy.

Bauer's law is fitted on the loading levels at rest (fit_ladder) with two pressure
measures: the vertical stress on the piston (Oquendo Eq. 19, p) and the trace of the
stress, sigma_v + 2 sigma_lateral = 3 p_s (Bauer's original mean stress; the
abstract's "3p").
"""
from typing import Literal

import numpy as np
from pydantic import model_validator

from ..analysis import bauer_sweep
from ..analysis.bauer import BauerFitError, fit_bauer
from ..analysis.energy import energy_budget
from ..analysis.packing import coordination_number
from ..core.triggers import Periodic
from ..core.walls import Motion, Plane
from ..core.engine import OverlapError
from ..schema import Float, described as _f
from .base import Protocol, ProtocolPhase, lower_onto_grains, register, write_rows
from .deposition import save_figure
from .phases import SettleSettings, preparation

PISTON = "piston"
MEASURES = bauer_sweep.PRESSURE_COLUMNS
# fewest loading levels at rest for a fit on those alone (Bauer's law has 3 parameters)
MIN_AT_REST = 5
BAND = 0.1  # the piston moves at full speed while the force error exceeds 10 % of the target


def ladder(p0, p_max, factor, unload=False):
    """The stress levels [Pa] as (target, branch): p0 factor^k up to p_max (p_max itself
    ends the ladder when it is not on it), then back down to p0 when ``unload``."""
    up = [p0]
    while up[-1] * factor < p_max * (1 + 1e-9):
        up.append(up[-1] * factor)
    if up[-1] < p_max * (1 - 1e-9):
        up.append(p_max)
    down = up[-2::-1] if unload else []
    return [(p, "loading") for p in up] + [(p, "unloading") for p in down]


class OedometerSettings(SettleSettings):
    """The oedometric test of Oquendo et al. Sec. 4: settle, then load the sample through
    a stress-controlled piston on a ladder p0, factor p0, ... up to p_max (optionally back
    down), relaxing at each level; fit Bauer's law (Oquendo Eq. 19)."""

    kind: Literal["oedometer"] = "oedometer"
    p0: Float = _f(12.5e3, "first vertical stress on the piston [Pa]; > 0", gt=0)
    p_max: Float = _f(3.2e6, "largest vertical stress [Pa]; >= p0", gt=0)
    factor: Float = _f(2.0, "stress ratio between levels [-] (2: doubling); (1, 10]", gt=1,
                       le=10)
    unload: bool = _f(False, "after p_max, unload by the same factor back to p0")
    piston_material: str | None = _f(None, "piston material; default: walls.material")
    loading: Literal["servo", "piston"] = _f(
        "servo", "how the piston is driven: servo (a velocity servo on its force error) or "
        "piston (a plate of piston_mass pushed by p A and by the grains)")
    piston_mass: Float | None = _f(None, "mass of the piston [kg] (loading = piston); "
                                   "default: the mass of the grains; > 0", gt=0)
    servo_time: Float = _f(1e-3, "servo time constant tau [s]: the piston closes its force "
                           "error no faster than exp(-t/tau); (0, 10]", gt=0, le=10)
    max_speed: Float = _f(0.01, "largest piston speed [m/s]; (0, 10]", gt=0, le=10)
    force_tolerance: Float = _f(0.01, "a level is at rest when |F_piston - F_target| <= "
                                "this fraction of F_target ...; (0, 0.5]", gt=0, le=0.5)
    rest_ratio: Float = _f(1e-4, "... and kinetic <= this fraction of the elastic energy of "
                           "the contacts (rigid grains: of p A R_mean) [-]; > 0", gt=0)
    level_max_time: Float = _f(0.05, "longest relaxation per level [s] of simulated time "
                               "(the level is then recorded as not at rest); (0, 100]",
                               gt=0, le=100)
    level_min_time: Float = _f(0.0, "shortest relaxation per level [s] of simulated time: "
                               "a level at rest earlier is held under its load until then "
                               "(laboratories wait minutes per level); [0, level_max_time]",
                               ge=0)

    @model_validator(mode="after")
    def _ladder(self):
        if self.p_max < self.p0:
            raise ValueError(f"protocol.p_max = {self.p_max} Pa is below p0 = {self.p0} Pa")
        if self.level_min_time > self.level_max_time:
            raise ValueError(f"protocol.level_min_time = {self.level_min_time} s is longer "
                             f"than level_max_time = {self.level_max_time} s")
        return self


@register
class Oedometer(Protocol):
    """Oedometric compression of a settled sample under a stress-controlled piston."""

    kind = "oedometer"
    settings = OedometerSettings
    summary = ("settle, then load through a stress-controlled piston level by level and "
               "fit Bauer's law (Oquendo et al. Sec. 4)")
    summarize_sweep = staticmethod(bauer_sweep.summarize_sweep)

    def __init__(self, settings, vessel):
        super().__init__(settings, vessel.closed())    # the piston starts at its top
        self.phases = (*preparation(settings, vessel), Load(self))

    @classmethod
    def wall_motions(cls, settings):
        """The piston is a servo or a wall of a mass (``loading``)."""
        return {settings.loading}

    @classmethod
    def cross_check(cls, config):
        settings = config.protocol
        settings.check_dim(config.run.dim)
        box = config.walls.container
        if config.run.dim != 3 or getattr(box, "kind", None) == "box" and not box.open_top:
            raise ValueError("the oedometer protocol needs run.dim = 3 and a cylinder or an "
                             "open-top box (the piston closes it)")

    @classmethod
    def materials_named(cls, settings):
        return [("protocol.piston_material", settings.piston_material)] \
            if settings.piston_material is not None else []

    def walls(self, container, material_index):
        """The container and the piston: a plane at its top, facing down, of
        piston_material (None: the walls' material, material_index(None))."""
        v = self.vessel
        material = material_index(self.p.piston_material)
        center = v.center if v.center is not None \
            else tuple(0.5 * (np.asarray(v.lo[:2]) + v.hi[:2]))
        return list(container) + [Plane((*center, v.top), (0.0, 0.0, -1.0), material,
                                        name=PISTON, area=v.cross_section)]

    # ------------------------------------------------------------------ results
    def results(self, sim, states):
        """The settled sample, the ladder and Bauer's law fitted with both measures."""
        out = {"deposition": states["settle"]["report"]}
        rows = states["load"]["rows"]
        out["ladder"] = rows
        if "stopped_early" in states["load"]:
            out["stopped_early"] = states["load"]["stopped_early"]
        out["bauer"] = fit_ladder(rows)
        out["bauer_note"] = (
            "vertical: p = stress on the piston (Oquendo Eq. 19, the paper's Tables 2-3); "
            "trace: 3 p_s = sigma_v + 2 sigma_lateral (Bauer 1996; the abstract's 3p)")
        return out

    def series_columns(self, engine):
        """The piston's height above the bottom [m] and the void ratio below it (as each
        level records them): how the sample creeps under a held load.  Before the load
        phase the piston waits at the top of the container."""
        height = piston_height(engine.walls, self.vessel)
        return {"piston_height [m]": height,
                "void_ratio [-]": void_ratio(engine.state, self.vessel, height)}

    def tables(self, rundir, results):
        """ladder.csv: one row per level."""
        return [write_rows(rundir.path / "ladder.csv", results["ladder"])]

    def figures(self, rundir, series, results):
        """e against p on linear and log axes with the fitted curves (as Oquendo Fig.
        3/4), and the piston force against time."""
        from ..figures import subplots

        rows = results["ladder"]
        fig, axes = subplots(1, 3, figsize=(15, 4.2))
        for ax, log in zip(axes[:2], (False, True)):
            for measure, key, color in (("vertical", "sigma_top_Pa", "C0"),
                                        ("trace", "trace_Pa", "C1")):
                for branch, marker in (("loading", "o"), ("unloading", "s")):
                    sel = [r for r in rows if r["branch"] == branch]
                    if sel:
                        ax.plot([r[key] / 1e6 for r in sel], [r["void_ratio"] for r in sel],
                                marker, color=color, mfc="none" if branch == "unloading"
                                else color, label=f"{measure} ({branch})")
                fit = results["bauer"][measure]
                loaded = [r[key] for r in rows if r[key] > 0]   # a level the piston reached
                if "h_s_Pa" in fit and loaded:
                    p = np.geomspace(min(loaded), max(loaded))
                    ax.plot(p / 1e6, fit["e0"] * np.exp(-(p / fit["h_s_Pa"]) ** fit["eta"]),
                            "-", color=color, label=f"Bauer, {measure}: h_s = "
                            f"{fit['h_s_Pa'] / 1e6:.3g} MPa, eta = {fit['eta']:.3g}")
            ax.set(xlabel="p [MPa]", ylabel="void ratio e [-]")
            if log:
                ax.set_xscale("log")
        axes[0].legend(fontsize=7)
        t = series["time [s]"]
        stress = series[f"force_{PISTON} [N]"] / self.vessel.cross_section
        axes[2].plot(t, stress / 1e6)
        axes[2].set(xlabel="t [s]", ylabel="piston stress [MPa]")
        if "void_ratio [-]" in series:       # runs of older versions lack it
            loaded = stress >= 0.5 * self.p.p0      # the piston down on the sample
            creep = axes[2].twinx()
            creep.plot(t[loaded], series["void_ratio [-]"][loaded], color="C3", lw=0.8)
            creep.set_ylabel("void ratio e [-]", color="C3")
        fig.suptitle(f"{self.title}: oedometric test, "
                     f"{results['deposition'].get('grains', '?')} grains")
        return [save_figure(fig, rundir, "oedometer.png")]


class Load(ProtocolPhase):
    """The load phase: the piston put just above the highest grain, then driven as a
    stress-controlled wall up and down the protocol's ladder (module docstring)."""

    name = "load"

    def __init__(self, protocol):
        super().__init__(protocol)
        self.levels = ladder(self.p.p0, self.p.p_max, self.p.factor, self.p.unload)

    def duration(self):
        return self.p.level_max_time * len(self.levels)

    def log(self, message):
        self.protocol.log(message)

    def run(self, sim, state, *, every=(), between=None):
        p = self.p
        k = sim.walls.index(PISTON)
        if "level" not in state:
            lower_onto_grains(sim, k)
            state.update(level=0, rows=[])
            self._arm(sim, state, k)
        interrupted = []

        def check(sim):
            """At every pause (at least every servo_time/4): tune the servo's gain, keep
            the peak, end a level at rest; stop for the runner or at the level's end."""
            if p.loading == "servo" and not sim.rigid:
                self._tune(sim, k, state)
            state["peak"] = max(state.get("peak", 0.0), sim.walls.normal_force(k))
            if sim.time >= state["level_end"] - p.level_max_time + p.level_min_time \
                    and self._at_rest(sim, k):
                self._finish_level(sim, state, k, True)
            if between is not None and between(sim):
                interrupted.append(True)
                return True
            return "level_end" not in state or state["level_end"] != end

        pauses = [*every, (Periodic(time=p.servo_time / 4), lambda sim: None)]
        while state["level"] < len(self.levels):
            end = state["level_end"]
            level = state["level"]
            try:
                sim.run(time=max(0.0, end - sim.time), every=pauses, between=check)
            except OverlapError as err:
                self._stop_early(state, err)
                break
            if interrupted:
                return "stopped"
            if state["level"] == level:
                self._finish_level(sim, state, k, False)
        sim.set_motion(k, Motion("fixed"))
        return "done"

    def _stop_early(self, state, err):
        """The load outgrew the contact law (an overlap above overlap_limit): end the
        ladder at the current level, keep the levels done and say so."""
        target, branch = self.levels[state["level"]]
        state["stopped_early"] = {"level": state["level"], "branch": branch,
                                  "target_Pa": target, "reason": str(err)}
        state["level"] = len(self.levels)
        state.pop("level_end", None)
        self.log(f"ladder stopped at level {state['stopped_early']['level']} ({branch}, "
                 f"p = {target:.4g} Pa): {err}; the results keep the "
                 f"{len(state['rows'])} levels done")

    def _arm(self, sim, state, k):
        """Start the current level: the piston's force p A (loading = piston), or the
        servo's target force and its gain no higher than v_max/(BAND F_target) (the
        whole bound at the first level, when the piston becomes a servo moving down at
        up to v_max), and the level's deadline."""
        p = self.p
        target = self.levels[state["level"]][0] * self.vessel.cross_section
        state["level_end"] = sim.time + p.level_max_time
        if p.loading == "piston":
            mass = p.piston_mass if p.piston_mass is not None \
                else float(np.sum(sim.state.masses))
            sim.set_motion(k, Motion("piston", direction=(0.0, 0.0, -1.0), force=target,
                                     mass=mass))
            return
        bound = p.max_speed / (BAND * target)
        gain = min(sim.walls.motion_of(k).gain, bound) if state["level"] else bound
        sim.set_servo(k, force=target, gain=gain, max_speed=p.max_speed,
                      direction=(0.0, 0.0, -1.0))

    def _tune(self, sim, k, state):
        """Servo gain g = min(v_max/(BAND F_target), 1/(tau K)), K the sample's stiffness seen
        by the piston: the secant dF/dz since the last call, capped by the stiffness of
        the piston's contacts (the sample behind them is softer); no cap when the sample
        yields (dF/dz <= 0).  The last (z, F) is kept in ``state`` (checkpointed)."""
        p = self.p
        servo = sim.walls.motion_of(k)
        target = servo.force
        z = float(sim.walls.offset[k, 2])
        force = sim.walls.normal_force(k)
        gain = p.max_speed / (BAND * target)
        z_last, f_last = state.get("servo", (z, force))
        if z_last != z:
            stiffness = min((force - f_last) / (z_last - z), self._contact_stiffness(sim, k))
            if stiffness > 0:
                gain = min(gain, 1.0 / (p.servo_time * stiffness))
        elif "servo" in state:
            gain = servo.gain
        state["servo"] = (z, force)
        sim.set_servo(k, gain=gain)

    @staticmethod
    def _contact_stiffness(sim, k):
        """An upper bound of the tangent stiffness [N/m] of the contacts on wall k: sum
        of 1.5 F_c/delta_c, the overlap delta_c = R - |branch| of each.  A contact law
        F ~ delta^a has the tangent stiffness a F/delta: exact for Hertz (a = 3/2), an
        upper bound for the linear spring (a = 1), which only lowers the gain; rigid
        grains (no overlap) add nothing."""
        contacts = sim.wall_contacts()
        mine = contacts.wall == k
        overlap = sim.state.radii[contacts.grain[mine]] \
            - np.linalg.norm(contacts.branch[mine], axis=1)
        ok = overlap > 0
        return float(np.sum(1.5 * contacts.normal_force[mine][ok] / overlap[ok]))

    def _at_rest(self, sim, k):
        """Piston force on target, the sample in static equilibrium (bottom force plus
        side-wall friction carry the piston force plus the weight, within the same
        tolerance: an oscillation caught at its turning point has no kinetic energy but
        does not balance) and the kinetic energy small against the elastic energy (rigid
        grains: against p A R_mean, the work of the load over a mean radius)."""
        p = self.p
        walls = sim.walls
        target = walls.motion_of(k).force
        piston = walls.normal_force(k)
        if abs(piston - target) > p.force_tolerance * target:
            return False
        bottom = walls.normal_force(walls.index(self.vessel.bottom_wall))
        friction = self._side_friction(sim)
        if abs(bottom + friction - piston - self._weight(sim)) > p.force_tolerance * target:
            return False
        e = energy_budget(sim)
        reference = target * float(np.mean(sim.state.radii)) if sim.rigid else e["elastic"]
        return e["kinetic"] + e["rotational"] <= p.rest_ratio * reference

    def _side_friction(self, sim):
        """Vertical force [N] the side walls carry by friction (upward on the grains)."""
        walls = sim.walls
        return -float(np.sum(walls.force[[walls.index(n) for n in self.vessel.side_walls], 2]))

    @staticmethod
    def _weight(sim):
        """Weight [N] of the free grains."""
        return float(np.sum(sim.state.masses[sim.state.fixed == 0])) * float(-sim.gravity[2])

    def _finish_level(self, sim, state, k, at_rest):
        target, branch = self.levels[state["level"]]
        row = {"level": state["level"], "branch": branch, "target_Pa": target,
               "at_rest": at_rest, **self.measure(sim),
               "peak_over_target": state.pop("peak", 0.0) / (target * self.vessel.cross_section)}
        self.log(f"level {row['level']} ({branch}) p = {target:.4g} Pa: sigma_top = "
                 f"{row['sigma_top_Pa']:.4g} Pa, e = {row['void_ratio']:.5f}, "
                 f"{'at rest' if at_rest else 'NOT at rest'} at t = {sim.time:.5g} s")
        state["rows"].append(row)
        state["level"] += 1
        del state["level_end"]
        if state["level"] < len(self.levels):
            self._arm(sim, state, k)

    def measure(self, sim):
        """The oedometer's state: stresses [Pa], K0, void ratio, friction on the side
        walls [N], coordination and kinetic energy [J] (see the module docstring)."""
        walls = sim.walls
        piston, bottom = walls.index(PISTON), walls.index(self.vessel.bottom_wall)
        height = piston_height(walls, self.vessel)
        sides = [walls.index(name) for name in self.vessel.side_walls]
        contacts = sim.wall_contacts()
        lateral = float(np.sum(contacts.normal_force[np.isin(contacts.wall, sides)])) \
            / (self.vessel.perimeter * height)
        top = walls.normal_force(piston) / self.vessel.cross_section
        bot = walls.normal_force(bottom) / self.vessel.cross_section
        vertical = 0.5 * (top + bot)
        weight = self._weight(sim)
        e = energy_budget(sim)
        return {"sigma_top_Pa": top, "sigma_bottom_Pa": bot, "sigma_lateral_Pa": lateral,
                "K0": lateral / vertical if vertical > 0 else float("nan"),
                "trace_Pa": top + 2.0 * lateral,
                "void_ratio": void_ratio(sim.state, self.vessel, height),
                "height_m": height, "side_friction_N": self._side_friction(sim),
                "weight_N": weight, "coordination": coordination_number(sim),
                "kinetic_J": e["kinetic"] + e["rotational"], "elastic_J": e["elastic"],
                "time_s": sim.time}



def piston_height(walls, vessel):
    """Height [m] of the piston above the container's bottom."""
    piston, bottom = walls.index(PISTON), walls.index(vessel.bottom_wall)
    return float(walls.geometry[piston, 2] + walls.offset[piston, 2]
                 - walls.geometry[bottom, 2] - walls.offset[bottom, 2])


def void_ratio(state, vessel, height):
    """e = (V - V_s)/V_s of the sample below a piston at ``height`` [m], V_s the sum of
    the grains' volumes (overlaps neglected)."""
    solid = float(np.sum(4.0 / 3.0 * np.pi * state.radii**3))
    return (vessel.cross_section * height - solid) / solid


def fit_ladder(rows):
    """Bauer's law on the loading rows with each pressure measure: the fit's as_dict()
    plus "levels" (the level numbers fitted) and "not_at_rest" (the loading levels left
    out), or {"error": message} when the data cannot be fitted.

    Only levels at rest are fitted: a sample still creeping at the end of
    ``level_max_time`` has not reached the void ratio of its load.  When fewer than
    MIN_AT_REST loading levels are at rest, all of them are fitted and "not_at_rest"
    lists those that were not, so the fit is never silently made of moving samples."""
    loading = [r for r in rows if r["branch"] == "loading"]
    moving = [r["level"] for r in loading if not r["at_rest"]]
    if len(loading) - len(moving) >= MIN_AT_REST:
        loading = [r for r in loading if r["at_rest"]]
    fits = {}
    for measure, key in MEASURES.items():
        try:
            fit = fit_bauer([r[key] for r in loading], [r["void_ratio"] for r in loading],
                            pressure=measure)
            fits[measure] = {**fit.as_dict(), "levels": [r["level"] for r in loading],
                             "not_at_rest": moving}
        except BauerFitError as err:
            fits[measure] = {"pressure": measure, "error": str(err)}
    return fits
