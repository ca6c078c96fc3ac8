"""The oedometric test of Oquendo et al. (Sec. 4) and the fit of Bauer's law (Eq. 19).

Phases: "settle" (the deposition protocol: grains inserted at random in the container,
settled under gravity) and "load": the piston, a plane above the sample, is put just
over the highest grain and becomes a stress-controlled wall (core.walls, servo motion)
with target force p A for the levels p = p0, factor p0, ... up to p_max, and back down
when ``unload`` is set.  At each level the sample relaxes until it is at rest:

    |F_piston - p A| <= force_tolerance p A,
    |F_bottom + F_side friction - F_piston - weight| <= force_tolerance p A   and
    E_kin + E_rot <= rest_ratio E_elastic,

checked between compiled chunks (at most servo_time/4 apart), or until level_max_time
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
u leaves a force error of 0.1 p A u/v_max until it stops creeping.

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
import math

import numpy as np

from ..analysis.bauer import BauerFitError, fit_bauer
from ..analysis.energy import energy_budget
from ..analysis.packing import coordination_number
from ..config import build
from ..config.models import BoxContainer, Config
from ..core.walls import Motion, Plane
from ..engines.soft.simulation import OverlapError, Simulation
from .deposition import Deposition, save_figure

PISTON = "piston"
MEASURES = {"vertical": "sigma_top_Pa", "trace": "trace_Pa"}
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


class Oedometer(Deposition):
    """Oedometric compression of a settled sample under a stress-controlled piston."""

    phases = ("settle", "load")

    def __init__(self, config: Config):
        super().__init__(config)
        p = config.protocol
        self.levels = ladder(p.p0, p.p_max, p.factor, p.unload)
        box = config.walls.container
        self.ceiling = box.hi[-1] if isinstance(box, BoxContainer) else box.height
        self.side_walls = ("xlo", "xhi", "ylo", "yhi") if isinstance(box, BoxContainer) \
            else ("side",)
        self.perimeter = 2 * float(np.sum(np.subtract(box.hi, box.lo)[:2])) \
            if isinstance(box, BoxContainer) else 2 * math.pi * box.radius

    def build(self, state):
        """The Simulation with the container's walls plus the piston at the top."""
        kwargs = build.simulation_kwargs(self.config)
        c, box = self.config, self.config.walls.container
        material = c.material_index(c.protocol.piston_material or c.walls.material)
        center = tuple(0.5 * (np.asarray(box.lo[:2]) + box.hi[:2])) \
            if isinstance(box, BoxContainer) else box.center
        piston = Plane((*center, self.ceiling), (0.0, 0.0, -1.0), material, name=PISTON,
                       area=self.cross_section)
        kwargs["walls"] = kwargs["walls"] + [piston]
        return Simulation(state, **kwargs)

    def phase_duration(self, name):
        """Longest simulated time [s] of a phase (for the progress bar)."""
        if name == "load":
            return self.config.protocol.level_max_time * len(self.levels)
        return super().phase_duration(name)

    # ------------------------------------------------------------------ the load phase
    def run_phase(self, phase, sim, state, **run):
        if phase == "settle":
            status = super().run_phase(phase, sim, state, **run)
            if status != "stopped":
                state["report"] = super().results(sim, {"settle": state})
            return status
        return self._load(sim, state, **run)

    def _load(self, sim, state, every=(), between=None, max_chunk=20000):
        p = self.config.protocol
        k = sim.walls.index(PISTON)
        if "level" not in state:
            top = float(np.max(sim.state.positions[:, 2] + sim.state.radii))
            offset = sim.walls.offset[k].copy()
            offset[2] = top + 1e-3 * float(sim.state.radii.min()) - sim.walls.geometry[k, 2]
            sim.place_wall(k, offset)
            state.update(level=0, rows=[])
            self._arm(sim, state, k)
        chunk = int(max(1, min(max_chunk, p.servo_time / (4 * sim.dt))))
        interrupted = []

        def check(sim):
            self._tune(sim, k, state)
            state["peak"] = max(state.get("peak", 0.0), sim.walls.normal_force(k))
            if self._at_rest(sim, k):
                self._finish_level(sim, state, k, True)
            if between is not None and between(sim):
                interrupted.append(True)
                return True
            return "level_end" not in state or state["level_end"] != end

        while state["level"] < len(self.levels):
            end = state["level_end"]
            level = state["level"]
            try:
                sim.run(steps=end - sim.step, every=every, between=check, max_chunk=chunk)
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
        """Start the current level: the servo's target force, its gain no higher than
        v_max/(BAND F_target) (the whole bound at the first level, when the piston
        becomes a servo moving down at up to v_max) and the level's deadline."""
        p = self.config.protocol
        target = self.levels[state["level"]][0] * self.cross_section
        bound = p.max_speed / (BAND * target)
        gain = min(sim.walls.motion_of(k).gain, bound) if state["level"] else bound
        sim.set_servo(k, force=target, gain=gain, max_speed=p.max_speed,
                      direction=(0.0, 0.0, -1.0))
        state["level_end"] = sim.step + math.ceil(p.level_max_time / sim.dt - 1e-9)

    def _tune(self, sim, k, state):
        """Servo gain g = min(v_max/(BAND F_target), 1/(tau K)), K the sample's stiffness seen
        by the piston: the secant dF/dz since the last call, capped by the stiffness of
        the piston's contacts (the sample behind them is softer); no cap when the sample
        yields (dF/dz <= 0).  The last (z, F) is kept in ``state`` (checkpointed)."""
        p = self.config.protocol
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
        """Tangent stiffness [N/m] of the contacts on wall k: sum of 1.5 F_c/delta_c
        (Hertz), the overlap delta_c = R - |branch| of each."""
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
        does not balance) and the kinetic energy small against the elastic energy."""
        p = self.config.protocol
        walls = sim.walls
        target = walls.motion_of(k).force
        piston = walls.normal_force(k)
        if abs(piston - target) > p.force_tolerance * target:
            return False
        bottom = walls.normal_force(walls.index(self.bottom_wall))
        friction = self._side_friction(sim)
        if abs(bottom + friction - piston - self._weight(sim)) > p.force_tolerance * target:
            return False
        e = energy_budget(sim)
        return e["kinetic"] + e["rotational"] <= p.rest_ratio * e["elastic"]

    def _side_friction(self, sim):
        """Vertical force [N] the side walls carry by friction (upward on the grains)."""
        walls = sim.walls
        return -float(np.sum(walls.force[[walls.index(n) for n in self.side_walls], 2]))

    @staticmethod
    def _weight(sim):
        """Weight [N] of the free grains."""
        return float(np.sum(sim.state.masses[sim.state.fixed == 0])) * float(-sim.gravity[2])

    def _finish_level(self, sim, state, k, at_rest):
        target, branch = self.levels[state["level"]]
        row = {"level": state["level"], "branch": branch, "target_Pa": target,
               "at_rest": at_rest, **self.measure(sim),
               "peak_over_target": state.pop("peak", 0.0) / (target * self.cross_section)}
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
        walls, s = sim.walls, sim.state
        piston, bottom = walls.index(PISTON), walls.index(self.bottom_wall)
        z_top = float(walls.geometry[piston, 2] + walls.offset[piston, 2])
        z_bottom = float(walls.geometry[bottom, 2] + walls.offset[bottom, 2])
        height = z_top - z_bottom
        solid = float(np.sum(4.0 / 3.0 * np.pi * s.radii**3))
        sides = [walls.index(name) for name in self.side_walls]
        contacts = sim.wall_contacts()
        lateral = float(np.sum(contacts.normal_force[np.isin(contacts.wall, sides)])) \
            / (self.perimeter * height)
        top = walls.normal_force(piston) / self.cross_section
        bot = walls.normal_force(bottom) / self.cross_section
        vertical = 0.5 * (top + bot)
        weight = self._weight(sim)
        e = energy_budget(sim)
        return {"sigma_top_Pa": top, "sigma_bottom_Pa": bot, "sigma_lateral_Pa": lateral,
                "K0": lateral / vertical if vertical > 0 else float("nan"),
                "trace_Pa": top + 2.0 * lateral, "void_ratio": (self.cross_section * height
                                                               - solid) / solid,
                "height_m": height, "side_friction_N": self._side_friction(sim),
                "weight_N": weight, "coordination": coordination_number(sim),
                "kinetic_J": e["kinetic"] + e["rotational"], "elastic_J": e["elastic"],
                "time_s": sim.time, "step": sim.step}

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

    def tables(self, rundir, results):
        """ladder.csv: one row per level."""
        rows = results["ladder"]
        keys = list(rows[0]) if rows else []
        lines = [",".join(keys)] + [",".join(str(r[k]) for k in keys) for r in rows]
        path = rundir.path / "ladder.csv"
        path.write_text("\n".join(lines) + "\n")
        return [path]

    def figures(self, rundir, series, results):
        """e against p on linear and log axes with the fitted curves (as Oquendo Fig.
        3/4), and the piston force against time."""
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        rows = results["ladder"]
        fig, axes = plt.subplots(1, 3, figsize=(15, 4.2))
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
                if "h_s_Pa" in fit:
                    p = np.geomspace(min(r[key] for r in rows), max(r[key] for r in rows))
                    ax.plot(p / 1e6, fit["e0"] * np.exp(-(p / fit["h_s_Pa"]) ** fit["eta"]),
                            "-", color=color, label=f"Bauer, {measure}: h_s = "
                            f"{fit['h_s_Pa'] / 1e6:.3g} MPa, eta = {fit['eta']:.3g}")
            ax.set(xlabel="p [MPa]", ylabel="void ratio e [-]")
            if log:
                ax.set_xscale("log")
        axes[0].legend(fontsize=7)
        t = series["time [s]"]
        axes[2].plot(t, series[f"force_{PISTON} [N]"] / self.cross_section / 1e6)
        axes[2].set(xlabel="t [s]", ylabel="piston stress [MPa]")
        fig.suptitle(f"{self.config.run.name}: oedometric test, {self.config.grains.count} "
                     "grains")
        return [save_figure(fig, rundir, "oedometer.png")]


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
