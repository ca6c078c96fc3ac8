"""Cyclic loading of a confined granular bed through a rigid top plate (Karrech et al.,
Sec. 2 and 5, Fig. 2): the molecular-dynamics part of their long-term settlement study.

Phases: "settle" (grains spread at random in the container, settled under gravity until
E_kin/E_pot <= threshold, Karrech Sec. 3) and "cycles": the plate (a plane over the
whole top of the sample, or a finite plate over part of it: below) is put just above
the highest grain under it and becomes a piston (core.walls, piston motion) of mass
``plate_mass`` under gravity, pushed down by the stress signal

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
training data of analysis.settlement).  With the sequential procedure
(``extrapolation``) the overlaps of every contact before and after each relaxation go
to relaxations/to_cycle_NNNNNN.npz (``load_overlaps``), drawn in relaxation.png
(``relaxation_figure``, Karrech Fig. 9).  With ``jump_tolerance`` each jump is checked
on the cycles computed after it, the way an adaptive ODE solver checks a step: the
settlement rate r_after measured there against the rate r_jump the jump extrapolated,
h |r_after - r_jump| / 2 the difference between the forward jump and a trapezoidal
one; a jump whose estimate exceeds the tolerance (a fraction of the settlement) is
undone and the bed computed on instead.  This catches a jump made from a window still
in the bed's transient, whose end the cycles computed so far cannot show
(docs/settlement.md).  With ``jump_correction = "trapezoidal"`` no jump is undone:
each is corrected on the window after it to what the trapezoidal jump would have made,
as Heun's method corrects Euler's step, so that no measured window is thrown away.

Two modes (Karrech Sec. 5.3).  Fully confined (``plate_fraction = 1``, the default): the
plate is an infinite plane over the whole top of the sample.  Partially confined
(``plate_fraction`` < 1; the paper's case is "a confinement level of 80 %" at 5.87 kPa
and 10 Hz): the plate is a finite rigid plate centred on the container's axis whose
width is ``plate_fraction`` times the container's width, and the grains beside it are a
free surface.  Our reading of "80 % of the width", which the paper does not define
further: in a cylinder of radius R a disk (core.walls.Disk) of diameter fraction x 2R,
area pi (fraction R)^2 (0.64 of the cross-section at 80 %); in a 3D box of sides
L_x, L_y a rectangle (core.walls.Segment with a second edge) of sides fraction L_x,
fraction L_y, area fraction^2 L_x L_y, a copy of the cross-section scaled about its
centre as the disk is; in 2D a line segment of length fraction L_x (per unit depth).
The plate is thin and two-sided, and a grain at its edge touches the nearest point of
its rim.  The stress signal acts on the plate's own area A_p: the applied force is
A_p sigma(t) + M g, and the recorded sigma_plate is the plate's vertical force over A_p;
the settlement is the plate's descent as in the full mode.  The packing fraction is the
solid volume over the cross-section times the plate's height above the floor in both
modes (beside a partial plate the free surface may stand higher or lower).

With symmetry planes (the quarter model, protocols.base.Vessel.mirrored) the vessel is
the part of the container they leave: a partial plate is still the whole container's,
centred on the planes (a disk on the cylinder's axis), and its area, the stress's and
sigma_plate's, is the share of it on the grains' side, fraction^2 times that part's
cross-section.
"""
import json
import math
import pathlib
from typing import Literal

import numpy as np
from ..analysis.packing import coordination_number
from ..analysis.energy import energy_budget
from ..analysis.settlement import fit_residual, smooth_increments
from ..core.walls import Disk, Motion, Plane, Segment
from ..schema import Float, Int, described as _f
from .base import Protocol, ProtocolPhase, lower_onto_grains, register, run_until, write_rows
from .deposition import save_figure, settling_figure
from .phases import SettleSettings, preparation

PLATE = "plate"
PARK = 100.0
RELAXATIONS = "relaxations"     # the folder of the overlaps before and after each relaxation
PHASE_STATE = "phase_state"     # the phase's state beside the engine's arrays before a jump
SAFETY, SHRINK = 0.9, 0.2       # the jump controller's safety factor and its largest cut


def next_jump(h, error, tolerance, growth, order):
    """The next jump's length [cycles] after a jump of h cycles whose estimated error
    (over the settlement) was ``error``, chosen as an adaptive ODE solver chooses its
    step: kept (error <= tolerance), h 0.9 sqrt(tolerance / error), the forward jump's
    error growing as h^2, at most ``growth`` h; undone, h 0.9 (tolerance / error)^(1 /
    order), the error taken to grow as h^order (1: a rate difference that a shorter jump
    does not shrink, 2: the forward jump's), at least h / 5; at least one cycle."""
    if error <= tolerance:
        factor = min(growth, SAFETY * math.sqrt(tolerance / error) if error > 0
                     else math.inf)
    else:
        factor = max(SHRINK, SAFETY * (tolerance / error) ** (1.0 / order))
    return max(1, round(h * factor))


class CyclicSettings(SettleSettings):
    """Settle, then load the bed cyclically through a rigid top plate (Karrech et al.)
    over ``plate_fraction`` of the container's width: the stress on the plate's area a
    haversine of ``stress_amplitude`` at ``frequency`` above ``static_stress`` (module
    docstring), ``cycles`` cycles."""

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
    extrapolation: Literal["none", "linear", "shenton", "logarithmic"] = _f(
        "none", "the sequential procedure (Karrech Fig. 10): after initial_cycles, rounds "
        "of computed_cycles computed and extrapolated_cycles extrapolated by this "
        "estimator (Eq. 16, Eq. 17-21, or c + a ln t with t on the loading clock), then "
        "relaxed (Eq. 29); none: every cycle computed")
    initial_cycles: Int = _f(10, "k_i: cycles computed before the first extrapolation; "
                             ">= 1", ge=1)
    computed_cycles: Int = _f(10, "k: cycles computed per round, the training data of its "
                              "extrapolation; >= 2", ge=2)
    extrapolated_cycles: Int = _f(10, "h: cycles extrapolated in the first round; >= 1",
                                  ge=1)
    fit_time: Literal["loading", "window"] = _f(
        "loading", "the time origin of the Shenton and logarithmic laws in a round's fit: loading (t = pT "
        "from the start of the cycles, the paper's t + pT) or window (t = pT from the "
        "opening of the round's window, as if each round restarted the law: its log term "
        "then describes the window's own decay instead of tying the fit to the law's "
        "zero at the loading start)")
    restart_cycles: Int = _f(
        0, "computed cycles after each jump before the next round's window opens: the "
        "bed's own response to the jump (its first cycle settles more) is then left out "
        "of the next fit, and each later round computes computed_cycles + restart_cycles "
        "cycles; 0: the window opens at the jump's end (Karrech); >= 0", ge=0)
    extrapolated_growth: Float = _f(
        1.0, "the factor h grows by from one round to the next, h_r = round(h g^r) for "
        "round r = 0, 1, ... (Karrech Sec. 5: the error falls as the cycles computed so "
        "far grow, so h may grow with them); >= 1", ge=1)
    final_cycles: Int = _f(
        0, "cycles computed at the end: no jump reaches past cycles - final_cycles, so the "
        "run ends on computed cycles and its last state is a loaded bed, comparable with "
        "full DEM's (coordination, stresses), instead of a relaxed, unloaded one; 0: the "
        "last jump may end the run (Karrech); >= 0", ge=0)
    plate_fraction: Float = _f(
        1.0, "the fraction of the container's width the plate covers [-], in (0, 1]: 1 an "
        "infinite plane over the whole top (fully confined); < 1 a finite plate centred on "
        "the axis (partially confined): a disk of diameter fraction x the cylinder's "
        "diameter, or a rectangle of fraction x each side of a box (a segment of fraction "
        "x the width in 2D)", gt=0, le=1)
    relaxation: Literal["gravity", "overlaps", "excess", "excess_walls"] = _f(
        "gravity", "the functional each extrapolation is relaxed by: gravity (Karrech "
        "Eq. 29: the Hertz potentials and gravity, the plate a wall where it was put), "
        "overlaps (the Hertz potentials and springs of one grain weight per mean radius "
        "holding each grain where the extrapolation put it: the excessive overlaps "
        "are removed moving the grains as little as possible, gravity and the load "
        "coming back with the computed cycles) or excess (as overlaps, but each grain "
        "pair keeps the overlap it had at the end of the last computed cycle and only "
        "the excess is relaxed: the contacts between grains stay loaded, those with the "
        "walls and the plate are emptied) or excess_walls (as excess, and each grain-wall "
        "contact keeps the overlap it had there too, against the plate where it was "
        "before the jump: the plate and the floor stay loaded)")
    relaxation_iterations: Int = _f(10000, "most L-BFGS iterations of a relaxation [-]; "
                                    ">= 1", ge=1)
    relaxation_tolerance: Float = _f(1e-5, "largest residual force component a relaxation "
                                     "leaves, in mean grain weights [-]; > 0", gt=0)
    smoothing: Float = _f(
        0.0, "length over which the extrapolated increments are averaged, in mean grain "
        "radii [-] (analysis.settlement.smooth_increments: a Gaussian of that width over "
        "the grains within three of it, mirror images across the symmetry planes); 0: "
        "every grain moved by its own fitted trend (Karrech); >= 0", ge=0)
    smoothing_fit: Literal["mean", "linear"] = _f(
        "mean", "how the increments are averaged over the smoothing length "
        "(analysis.settlement.smooth_increments): mean (the Gaussian-weighted mean: "
        "next to the plate, the floor and the walls the neighbourhood is one-sided and "
        "the mean pulls the grains' increments towards those inside, the top grains' "
        "descent cut by about the strain rate times 0.8 smoothing radii) or linear (the "
        "affine field fitted to the neighbourhood by weighted least squares, evaluated "
        "at the grain: an affine field kept at every grain, boundaries included)")
    jump_tolerance: Float = _f(
        0.0, "the largest settlement error a jump may make, over the settlement at its "
        "end [-]: each jump is checked once the window after it has been computed, its "
        "error estimated as h |r_after - r_jump| / 2 (r_jump the plate's settlement rate "
        "the jump extrapolated at its end, r_after the rate the window measures: the "
        "forward jump against a trapezoidal one, as an adaptive ODE solver estimates its "
        "step's error); a jump above the tolerance is undone, the bed put back as it was "
        "before it (the clock running on), and the window slides on computed_cycles "
        "cycles before a jump is tried again; h is then chosen as such a solver chooses "
        "its step, h 0.9 sqrt(tol / error), at most extrapolated_growth h after a kept "
        "jump and at least h / 5 after an undone one.  Needs final_cycles >= restart_cycles "
        "+ computed_cycles, so that the last jump is checked too; 0: every jump kept "
        "(Karrech); >= 0", ge=0)
    undone_jump: Literal["slide", "retry"] = _f(
        "slide", "what follows a jump the check undid (jump_tolerance): slide (the window "
        "slides on computed_cycles cycles before the shorter jump is tried) or retry (the "
        "shorter jump is tried at once from the same window, as an adaptive ODE solver "
        "retries a rejected step from where it was: only the cycles computed after the "
        "undone jump are lost; when the shorter h is not shorter, as at h = 1, the window "
        "slides)")
    undone_error_order: Int = _f(
        2, "the power of h an undone jump's error is taken to grow as when the check "
        "chooses the shorter h (jump_tolerance): 2 (a forward jump's error, h^2 when the "
        "rate changes smoothly over it: h 0.9 sqrt(tol / error)) or 1 (a rate difference "
        "that does not shrink with h, as the noise of a ten-cycle window's slope or a "
        "transient the jump started in: h 0.9 tol / error, cut at once as far as that "
        "error needs); at least h / 5 either way; 1 or 2", ge=1, le=2)
    jump_correction: Literal["none", "trapezoidal"] = _f(
        "none", "what becomes of a checked jump (jump_tolerance) once the window after it "
        "is computed: none (kept within the tolerance, undone beyond it: undone_jump) or "
        "trapezoidal (always kept, and corrected to what the trapezoidal rule would have "
        "made of it, as Heun's method corrects Euler's step: every grain and the plate "
        "moved on by h (v_after - v_jump) / 2, v_jump the rate field the jump extrapolated "
        "at its end and v_after the one the window measures, then relaxed as a jump is; "
        "the next h chosen by the same controller, at least h / 5).  Measured over five "
        "pairs of beds it ends further from full DEM than undone jumps do (+7.7 +- 4.2 % "
        "against -3.5 +- 1.4 % at 1000 cycles, docs/settlement.md): a burst in the window "
        "after a jump is carried back over h / 2 cycles")
    keep_contacts: bool = _f(False, "the contacts still touching after an extrapolation and "
                             "its relaxation keep their history (tangential springs); "
                             "false: every contact starts unloaded (relocation)")
    hold_frontier: bool = _f(False, "hold the grains touching the container's walls where "
                             "the extrapolation put them while the others relax (Karrech "
                             "Sec. 4); false: every grain relaxes, the walls confining them")


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
    def wall_motions(cls, settings):
        """The loading plate is a piston (a wall of a mass under the cyclic stress)."""
        return {"piston"}

    @classmethod
    def cross_check(cls, config):
        settings = config.protocol
        settings.check_dim(config.run.dim)
        box = config.walls.container
        if getattr(box, "kind", None) == "box" and not box.open_top:
            raise ValueError("the cyclic protocol needs a cylinder or an open-top box (the "
                             "plate closes it)")
        if settings.extrapolation != "none" \
                and settings.initial_cycles + settings.final_cycles >= settings.cycles:
            raise ValueError(
                f"protocol.final_cycles = {settings.final_cycles} leaves no cycle to "
                f"extrapolate: initial_cycles + final_cycles must be below cycles = "
                f"{settings.cycles}")
        if settings.extrapolation != "none" and settings.jump_tolerance > 0 \
                and settings.final_cycles < settings.restart_cycles + settings.computed_cycles:
            raise ValueError(
                f"protocol.jump_tolerance checks each jump on the computed cycles after it: "
                f"final_cycles = {settings.final_cycles} must be at least restart_cycles + "
                f"computed_cycles = {settings.restart_cycles + settings.computed_cycles}, "
                f"so that the last jump is checked too")

        if settings.jump_correction != "none" and not (
                settings.extrapolation != "none" and settings.jump_tolerance > 0):
            raise ValueError(
                f"protocol.jump_correction = {settings.jump_correction!r} corrects each "
                "jump on the window checked after it: it needs an extrapolation and "
                "protocol.jump_tolerance > 0")

    @classmethod
    def materials_named(cls, settings):
        return [("protocol.plate_material", settings.plate_material)] \
            if settings.plate_material is not None else []

    def walls(self, container, material_index):
        """The container and the plate, parked PARK container heights above the floor
        (out of the way of a dilute cloud of grains: a solid fraction of 0.05 settles to
        about a tenth of its height) until the cycles put it on the bed: a plane facing
        down (plate_fraction = 1), or a disk, a rectangle (3D box) or a segment (2D)
        centred on the container's axis (plate_fraction < 1; plate_geometry)."""
        return list(container) + [plate_wall(self.p.plate_fraction, self.vessel,
                                             material_index(self.p.plate_material))]

    def results(self, engine, states):
        cycles = states["cycles"]
        out = {"deposition": states["settle"]["report"], "cycles": cycles["rows"],
               "extrapolations": cycles.get("jumps", []),
               "rejected_extrapolations": cycles.get("rejected", []),
               "signal": "sigma(t) = static + amplitude (1 - cos(2 pi f (t - t0))) / 2"}
        out["plate_fraction"] = self.p.plate_fraction
        out["plate_area_m2"] = plate_area(self.p.plate_fraction, self.vessel)
        last = [(r["cycle"], r["settlement_m"]) for r in out["cycles"]] + [
            (j["to_cycle"], j["settlement_m"]) for j in out["extrapolations"]]
        if last:
            out["settlement_m"] = max(last)[1]
        return out

    def tables(self, rundir, results):
        """cycles.csv: one row per cycle."""
        return [write_rows(rundir.path / "cycles.csv", results["cycles"])]

    def figures(self, rundir, series, results):
        """Settlement and coordination against the cycle number, and the plate stress
        against time (cyclic.png); the settling of the bed (settling.png: Karrech et
        al.'s Fig. 3, deposition.settling_figure)."""
        from ..figures import subplots

        rows = results["cycles"]
        fig, ax = subplots(1, 3, figsize=(15, 4.2))
        n = [r["cycle"] for r in rows]
        ax[0].plot(n, [1e3 * r["settlement_m"] for r in rows], "o-")
        ax[0].set(xlabel="cycle", ylabel="settlement [mm]")
        ax[1].plot(n, [r["coordination"] for r in rows], "o-")
        ax[1].set(xlabel="cycle", ylabel="coordination number [-]")
        t = series["time [s]"]
        ax[2].plot(t, series[f"force_{PLATE} [N]"] / results["plate_area_m2"] / 1e3)
        ax[2].set(xlabel="t [s]", ylabel="plate stress [kPa]")
        fig.suptitle(f"{self.title}: {len(rows)} load cycles, "
                     f"{results['deposition'].get('grains', '?')} grains")
        settled = results["deposition"]
        settling = settling_figure(
            series, settled, f"{self.title}: settling of {settled.get('grains', '?')} "
            f"grains, packing fraction {settled.get('packing_fraction', float('nan')):.3f}",
            self.vessel.bottom_wall)
        made = [save_figure(fig, rundir, "cyclic.png"),
                save_figure(settling, rundir, "settling.png")]
        if results["extrapolations"]:
            made.append(save_figure(relaxation_figure(rundir.path, self.title), rundir,
                                    "relaxation.png"))
        return made


class Cycles(ProtocolPhase):
    """The plate put on the bed, then ``cycles`` load cycles (module docstring)."""

    name = "cycles"
    _before = None      # (engine snapshot, phase state) before an unchecked jump

    def duration(self):
        return self.p.cycles / self.p.frequency

    def run(self, engine, state, *, every=(), between=None):
        p, v = self.p, self.vessel
        k = engine.walls.index(PLATE)
        up = v.dim - 1                                  # the vertical axis
        if "start_s" not in state:
            s = engine.state
            if p.plate_fraction == 1.0:
                lower_onto_grains(engine, k)
            else:
                seat_plate(engine, k)
            area = plate_area(p.plate_fraction, v)
            mass = p.plate_mass if p.plate_mass is not None else float(np.sum(s.masses))
            weight = mass * float(np.linalg.norm(engine.gravity))
            half = 0.5 * p.stress_amplitude * area
            direction = [0.0, 0.0, 0.0]
            direction[up] = -1.0
            engine.set_motion(k, Motion(
                "piston", direction=tuple(direction), mass=mass,
                force=p.static_stress * area + weight + half,
                force_amplitude=half, frequency=p.frequency, phase=-0.5 * np.pi,
                start=engine.time))
            state.update(start_s=engine.time, plate_0=self._plate(engine, k), rows=[],
                         reference=s.positions.tolist())
            state.update(cycle=0, jumps=[])
        while True:
            window_full = len(state.get("round", ())) > p.computed_cycles
            if "unchecked" in state and window_full and not self._check_jump(engine, state,
                                                                              k):
                continue                                # undone: the bed as before it
            if state["cycle"] >= p.cycles:
                break
            if p.extrapolation != "none" and window_full \
                    and state["cycle"] < p.cycles - p.final_cycles:
                self._jump(engine, state, k)
                continue
            outcome = run_until(engine, state, "cycle_end", 1.0 / p.frequency, every=every,
                                between=between)
            if outcome == "stopped":
                return "stopped"
            state["cycle"] += 1
            self._record(engine, state, k)
            del state["cycle_end"]
        engine.set_motion(k, Motion("fixed"))
        return "done"

    def _jump(self, engine, state, k):
        """The extrapolation of one round (Karrech Fig. 10): the estimator fitted to the
        positions of the grains and the plate over the round's computed cycles
        (analysis.settlement.fit_residual; times t_p = p T from the start of the
        cycles, Shenton's law as the paper fits it, without an intercept: with one, a
        window of a few cycles fits its noise and can extrapolate backwards), the
        grains and the plate moved to where it puts them h cycles on (with
        ``smoothing``, the grains' increments averaged over their neighbourhood first:
        analysis.settlement.smooth_increments), the grains then relaxed from rest
        (Eq. 29, engine.relax: Hertz potentials, gravity unless relaxation =
        "overlaps", the walls and the plate where they are; with hold_frontier the
        grains touching the container's walls held, as Karrech et al. do; with
        keep_contacts the contacts that persist keep their tangential history), and a
        new round starting from there."""
        p = self.p
        if not hasattr(engine, "relax") or not hasattr(engine, "rewind"):
            raise ValueError("the cyclic procedure needs an engine that can relax its "
                             "grains and rewind them (the soft engine)")
        records = state["round"]
        period = 1.0 / p.frequency
        first = state["cycle"] - p.computed_cycles
        if p.fit_time == "loading":
            times = period * np.arange(first, state["cycle"] + 1)
        else:
            times = period * np.arange(0, p.computed_cycles + 1)
        planned = state["next_h"] if "next_h" in state else \
            round(p.extrapolated_cycles * p.extrapolated_growth ** len(state["jumps"]))
        ahead = min(planned, p.cycles - p.final_cycles - state["cycle"])
        end = times[-1] + period * ahead
        law = p.extrapolation
        grains = np.array([r["positions"] for r in records])
        plates = np.array([r["plate"] for r in records])[:, None, :]
        moved, cycle_before = {}, {}
        for name, values in (("grains", grains), ("plate", plates)):
            trend = fit_residual(values - values[0], times, law)
            moved[name] = values[0] + trend.extrapolate(end)
            # where the trend has them a cycle before the end
            cycle_before[name] = values[0] + trend.extrapolate(end - period)
        last = grains[-1]
        if p.jump_correction != "none":     # the rates [m/cycle] at the jump's end
            state["jump_rates"] = {
                "grains": self._smooth(engine, last, moved["grains"]
                                       - cycle_before["grains"]).tolist(),
                "plate": (moved["plate"] - cycle_before["plate"])[0].tolist()}
        if p.smoothing > 0:
            moved["grains"] = last + self._smooth(engine, last, moved["grains"] - last)
        if p.jump_tolerance > 0 and p.jump_correction == "none":
            self._keep_before_jump(engine, state)
        up = self.vessel.dim - 1
        rate = float(cycle_before["plate"][0, up] - moved["plate"][0, up])  # descent [m/cycle]
        result = self._move_and_relax(engine, k, moved["grains"], moved["plate"][0], last)
        state["cycle"] += ahead
        jump = {"from_cycle": state["cycle"] - ahead, "to_cycle": state["cycle"],
                "estimator": law, "settlement_m": state["plate_0"] - self._plate(engine, k),
                "largest_overlap_before": result.overlaps_before.max,
                "largest_overlap_after": result.overlaps_after.max,
                "median_overlap_before": result.overlaps_before.p50,
                "median_overlap_after": result.overlaps_after.p50,
                "contacts_before": result.overlaps_before.count,
                "contacts_after": result.overlaps_after.count,
                "relaxation_iterations": result.iterations, "relaxed": result.converged,
                "functional_before_J": result.functional_before,
                "functional_after_J": result.functional_after,
                "extrapolated_rate_m_per_cycle": rate}
        state["jumps"].append(jump)
        if p.jump_tolerance > 0:
            state["unchecked"] = len(state["jumps"]) - 1
        self._save_residual(engine, state)
        self._save_overlaps(result, jump)
        state["round"] = [self._round_record(engine, k)] if p.restart_cycles == 0 else []
        state["window_opens"] = state["cycle"] + p.restart_cycles
        self.protocol.log(
            f"cycles {jump['from_cycle']} -> {jump['to_cycle']} extrapolated ({law}): "
            f"settlement {1e3 * jump['settlement_m']:.4g} mm; relaxed in "
            f"{result.iterations} iterations, largest overlap / radius "
            f"{jump['largest_overlap_before']:.3g} -> {jump['largest_overlap_after']:.3g}")

    def _smooth(self, engine, positions, increments):
        """The increments (N, 3) [m] of grains at ``positions`` averaged over
        ``smoothing`` mean radii (analysis.settlement.smooth_increments; unchanged
        without smoothing)."""
        if self.p.smoothing <= 0:
            return np.asarray(increments, dtype=np.float64)
        return smooth_increments(
            positions, increments, self.p.smoothing * float(np.mean(engine.state.radii)),
            planes=[(plane.index, plane.at) for plane in self.vessel.symmetry],
            fit=self.p.smoothing_fit)

    def _move_and_relax(self, engine, k, grains, plate, allowed):
        """The plate put at offset ``plate`` and the grains relaxed from ``grains`` (N,
        3) [m] (Eq. 29, engine.relax, as the ``relaxation`` setting says; ``allowed``:
        the positions whose overlaps relaxation = "excess" or "excess_walls" keeps, the
        latter against the walls where they are before the plate is put).  Returns the
        relaxation's result."""
        p = self.p
        held = engine.state.fixed != 0
        walls_before = engine.walls.offset.copy()
        engine.place_wall(k, plate)
        return engine.relax(fixed=held | self._frontier(engine, k) if p.hold_frontier
                            else held, force_tolerance=p.relaxation_tolerance,
                            gravity=p.relaxation == "gravity",
                            anchor=0.0 if p.relaxation == "gravity" else 1.0,
                            max_iterations=p.relaxation_iterations, start=grains,
                            keep_contacts=p.keep_contacts,
                            allowed=allowed if p.relaxation.startswith("excess") else None,
                            allowed_walls=walls_before if p.relaxation == "excess_walls"
                            else None)

    def _correct_jump(self, engine, state, k, jump, h):
        """The trapezoidal correction of the last jump (jump_correction): every grain and
        the plate moved on by h (v_after - v_jump) / 2, v_after the least-squares rate
        field [m/cycle] of the window computed after the jump (smoothed as the jump's
        increments were) and v_jump the one the jump extrapolated at its end, the grains
        relaxed from there; the window's records and the cycle's row and residuals
        shifted by what the grains and the plate moved, so that the next jump, which
        fits the window, starts from the corrected bed."""
        records = state["round"]
        grains = np.array([r["positions"] for r in records])
        plates = np.array([r["plate"] for r in records])
        cycles = np.arange(len(records), dtype=np.float64)
        n = grains.shape[1]
        slope = np.polyfit(cycles, grains.reshape(len(records), -1), 1)[0].reshape(n, -1)
        now = engine.state.positions.copy()
        rates = state.pop("jump_rates")
        grain_shift = 0.5 * h * (self._smooth(engine, now, slope) - np.asarray(rates["grains"]))
        plate_shift = 0.5 * h * (np.polyfit(cycles, plates, 1)[0] - np.asarray(rates["plate"]))
        plate_before = self._plate(engine, k)
        result = self._move_and_relax(engine, k, now + grain_shift,
                                      engine.walls.offset[k] + plate_shift, now)
        moved = engine.state.positions - now
        for r in records:
            r["positions"] = (np.asarray(r["positions"]) + moved).tolist()
            r["plate"] = (np.asarray(r["plate"]) + plate_shift).tolist()
        row = state["rows"][-1]
        plate = self._plate(engine, k)
        row.update(settlement_m=state["plate_0"] - plate, plate_height_m=plate)
        self._save_residual(engine, state)
        jump.update(correction_m=plate_before - plate,
                    correction_relaxation_iterations=result.iterations,
                    correction_largest_overlap_before=result.overlaps_before.max,
                    correction_largest_overlap_after=result.overlaps_after.max)

    def _check_jump(self, engine, state, k):
        """Check the last jump on the window computed after it (jump_tolerance): its
        settlement error estimated as h |r_after - r_jump| / 2 over the settlement at
        its end, r_after the least-squares slope of the plate's descent over the
        window's cycles [m per cycle], r_jump the rate the extrapolation had at the
        jump's end.  Within the tolerance the jump is kept (True); beyond it the bed,
        the phase's records and files go back to what they were before the jump
        (engine.rewind: the clock runs on by whole cycles, so the load's phase is the
        same), the rejected jump is listed in state["rejected"], and either the window
        slides on, computed_cycles more cycles before a shorter jump is tried, or
        (undone_jump = "retry") the shorter jump is made at once from the same window
        (False).  The
        next h is chosen as an adaptive solver chooses its step, the jump's error
        taken to grow as h^2 (the forward jump's): h times 0.9 sqrt(tol / error),
        at most extrapolated_growth times h after a kept jump; after an undone one the
        error is taken to grow as h^undone_error_order, h times 0.9 (tol / error)^(1 /
        order), and at least a fifth of h; at least one cycle."""
        p = self.p
        jump = state["jumps"][state["unchecked"]]
        up = self.vessel.dim - 1
        plates = np.array([r["plate"][up] for r in state["round"]])
        r_after = -float(np.polyfit(np.arange(plates.size), plates, 1)[0])
        h = jump["to_cycle"] - jump["from_cycle"]
        error = h * abs(r_after - jump["extrapolated_rate_m_per_cycle"]) \
            / (2.0 * abs(jump["settlement_m"]))
        corrected = p.jump_correction != "none"
        kept = corrected or error <= p.jump_tolerance
        jump.update(measured_rate_m_per_cycle=r_after, estimated_error=error,
                    checked_at_cycle=state["cycle"],
                    next_h=next_jump(h, error, p.jump_tolerance, p.extrapolated_growth,
                                     p.undone_error_order))
        del state["unchecked"]
        if corrected:
            self._correct_jump(engine, state, k, jump, h)
            state["next_h"] = jump["next_h"]
            self.protocol.log(f"jump {jump['from_cycle']} -> {jump['to_cycle']} corrected "
                              f"by {1e3 * jump['correction_m']:+.3g} mm: estimated error "
                              f"{error:.3g}, next h = {jump['next_h']}")
            return True
        if kept:
            state["next_h"] = jump["next_h"]
            self._forget_before_jump()
            self.protocol.log(f"jump {jump['from_cycle']} -> {jump['to_cycle']} kept: "
                              f"estimated error {error:.3g}")
            return True
        arrays, before = self._before_jump()
        for name, folder in (("cycle", "residuals"), ("to_cycle", RELAXATIONS)):
            if self.protocol.folder is not None:
                for f in (pathlib.Path(self.protocol.folder) / folder).glob(f"{name}_*.np*"):
                    if int(f.stem.removeprefix(f"{name}_")) > jump["from_cycle"]:
                        f.unlink()
        engine.rewind(arrays)
        rejected = state.get("rejected", []) + [jump]
        retry = p.undone_jump == "retry" and jump["next_h"] < h
        state.clear()
        state.update(before, rejected=rejected, next_h=jump["next_h"])
        if not retry:
            state["round"] = state["round"][-1:]
            state["window_opens"] = state["cycle"] + 1
        self._forget_before_jump()
        self.protocol.log(f"jump {jump['from_cycle']} -> {jump['to_cycle']} undone: "
                          f"estimated error {error:.3g} > {p.jump_tolerance:g} (rate "
                          f"{1e3 * jump['extrapolated_rate_m_per_cycle']:.3g} mm a cycle "
                          f"extrapolated, {1e3 * r_after:.3g} measured after it); "
                          + (f"retried at once with h = {jump['next_h']}" if retry else
                             f"the window slides on, then h = {jump['next_h']}"))
        return False

    def _before_jump_file(self):
        """Where the bed before an unchecked jump is kept (None without a run folder)."""
        if self.protocol.folder is None:
            return None
        return pathlib.Path(self.protocol.folder) / "procedure" / "before_jump.npz"

    def _keep_before_jump(self, engine, state):
        """Keep the engine's snapshot and the phase's state before a jump, in memory and
        (for a resumed run) in the run folder, until the jump is checked."""
        arrays = engine.snapshot()
        before = json.loads(json.dumps(state))
        self._before = arrays, before
        path = self._before_jump_file()
        if path is not None:
            path.parent.mkdir(exist_ok=True)
            partial = path.with_suffix(".partial.npz")
            np.savez(partial, **arrays, **{PHASE_STATE: np.array(json.dumps(before))})
            partial.replace(path)

    def _before_jump(self):
        """(engine snapshot, phase state) kept before the unchecked jump."""
        if self._before is None:
            path = self._before_jump_file()
            if path is None or not path.exists():
                raise RuntimeError("the bed before the unchecked jump is lost: "
                                   f"{path} is missing")
            with np.load(path) as data:
                arrays = {name: data[name] for name in data.files if name != PHASE_STATE}
                self._before = arrays, json.loads(str(data[PHASE_STATE]))
        return self._before

    def _forget_before_jump(self):
        self._before = None
        path = self._before_jump_file()
        if path is not None:
            path.unlink(missing_ok=True)

    def _frontier(self, engine, k):
        """(N,) bool: the grains touching a wall of the container (not the plate)."""
        s, walls = engine.state, engine.walls
        touching = np.zeros(s.n, bool)
        for w in range(len(walls)):
            if w != k:
                distance, _ = walls.distances(s.positions, np.full(s.n, w))
                touching |= distance < s.radii
        return touching

    def _round_record(self, engine, k):
        """The positions of the grains and the plate's offset, for a round's fit."""
        return {"positions": engine.state.positions.tolist(),
                "plate": engine.walls.offset[k].tolist()}

    def _save_residual(self, engine, state):
        """residuals/cycle_NNNNNN.npy of the cycle that ends now."""
        if self.p.residuals and self.protocol.folder is not None:
            folder = pathlib.Path(self.protocol.folder) / "residuals"
            folder.mkdir(exist_ok=True)
            np.save(folder / f"cycle_{state['cycle']:06d}.npy",
                    engine.state.positions - np.asarray(state["reference"]))

    def _save_overlaps(self, result, jump):
        """relaxations/to_cycle_NNNNNN.npz: every contact's overlap over the smaller
        radius [-] in the extrapolated configuration ("before") and after its
        relaxation ("after"), for the histograms of relaxation.png (Karrech Fig. 9)."""
        if self.protocol.folder is not None:
            folder = pathlib.Path(self.protocol.folder) / RELAXATIONS
            folder.mkdir(exist_ok=True)
            np.savez(folder / f"to_cycle_{jump['to_cycle']:06d}.npz",
                     before=result.overlaps_before.values,
                     after=result.overlaps_after.values)

    def _plate(self, engine, k):
        """Height [m] of the plate."""
        up = self.vessel.dim - 1
        return float(engine.walls.geometry[k, up] + engine.walls.offset[k, up])

    def _plate_force(self, engine, k):
        """Force [N] of the grains on the plate, upwards: the normal force of the plane
        (Walls.normal_force), the vertical component of the force on a finite plate
        (its friction on the grains left out)."""
        if self.p.plate_fraction == 1.0:
            return engine.walls.normal_force(k)
        return float(engine.walls.force[k, self.vessel.dim - 1])

    def _record(self, engine, state, k):
        """The row of the cycle that ends now, and its residual displacements."""
        v, s = self.vessel, engine.state
        walls = engine.walls
        cycle = state["cycle"]
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
               "sigma_plate_Pa": self._plate_force(engine, k)
               / plate_area(self.p.plate_fraction, v),
               "sigma_bottom_Pa": walls.normal_force(walls.index(v.bottom_wall))
               / v.cross_section, "sigma_lateral_Pa": lateral,
               "packing_fraction": solid / (v.cross_section * height),
               "coordination": coordination_number(engine),
               "mean_residual_m": float(np.mean(np.linalg.norm(residual, axis=1))),
               "kinetic_J": e["kinetic"] + e["rotational"]}
        state["rows"].append(row)
        self._save_residual(engine, state)
        if self.p.extrapolation != "none" and cycle >= state.get("window_opens",
                                                                 self.p.initial_cycles):
            state.setdefault("round", []).append(self._round_record(engine, k))
        self.protocol.log(f"cycle {cycle}: settlement {1e3 * row['settlement_m']:.4g} mm, "
                          f"coordination {row['coordination']:.3f}")


def plate_geometry(fraction, vessel):
    """The plate over ``fraction`` (0, 1] of the width of ``vessel`` (protocols.base.Vessel),
    centred on its axis, its face at height 0: ("plane", point, normal) for fraction 1;
    ("disk", centre, normal, radius [m]) in a cylinder; ("rectangle", corner, edge_x,
    edge_y) in a 3D box and ("segment", start, end) in 2D, their edges fraction times
    the box's sides [m] (module docstring).  The normal points down, into the grains.
    With symmetry planes (Vessel.mirrored) the plate is that of the whole container,
    centred on the planes, and the grains see the part of it on their side."""
    v = vessel
    down = (0.0, -1.0, 0.0) if v.dim == 2 else (0.0, 0.0, -1.0)
    centre = np.zeros(3)
    width = np.subtract(v.hi[:-1], v.lo[:-1])
    if v.center is not None:
        centre[:2] = v.center
    else:
        centre[:v.dim - 1] = 0.5 * (np.asarray(v.lo[:-1]) + v.hi[:-1])
    for plane in v.symmetry:               # the whole container's middle and sides
        centre[plane.index] = plane.at
        width[plane.index] *= 2.0
    if fraction == 1.0:
        return "plane", tuple(centre), down
    if v.shape == "cylinder":
        return "disk", tuple(centre), down, fraction * v.radius
    half = 0.5 * fraction * width
    if v.dim == 2:
        return "segment", (centre[0] - half[0], 0.0, 0.0), (centre[0] + half[0], 0.0, 0.0)
    corner = (centre[0] - half[0], centre[1] - half[1], 0.0)
    return "rectangle", corner, (2.0 * half[0], 0.0, 0.0), (0.0, 2.0 * half[1], 0.0)


def plate_area(fraction, vessel):
    """Area [m^2] (2D: length [m], per unit depth) of the part of the plate over
    ``fraction`` of the width of ``vessel`` that the grains see: fraction^(dim - 1)
    times the vessel's cross-section, i.e. pi (fraction R)^2 in a cylinder of radius R,
    fraction^2 L_x L_y in a 3D box, fraction L_x in 2D, the share of it the symmetry
    planes leave (Vessel.mirrored) with them; the cross-section for fraction 1."""
    if fraction == 1.0:
        return vessel.cross_section
    return fraction ** (vessel.dim - 1) * vessel.cross_section


def plate_wall(fraction, vessel, material, height=None):
    """The plate wall (core.walls) named PLATE of plate_geometry, at ``height`` [m]
    (default: PARK container heights above the floor), its area plate_area: a Plane
    (fraction 1), a Disk (cylinder) or a Segment (a rectangle in a 3D box, a line
    segment in 2D)."""
    v = vessel
    up = v.dim - 1
    if height is None:
        height = v.floor + PARK * (v.top - v.floor)
    kind, *shape = plate_geometry(fraction, v)
    lift = np.zeros(3)
    lift[up] = height
    area = plate_area(fraction, v)
    if kind == "plane":
        point, normal = shape
        return Plane(tuple(point + lift), normal, material, name=PLATE, area=area)
    if kind == "disk":
        centre, normal, radius = shape
        return Disk(tuple(centre + lift), normal, radius, material, name=PLATE, area=area)
    if kind == "segment":
        start, end = shape
        return Segment(tuple(start + lift), tuple(end + lift), material, name=PLATE,
                       area=area)
    corner, edge_x, edge_y = shape
    return Segment(tuple(corner + lift), tuple(corner + lift + edge_x), material,
                   name=PLATE, area=area, edge=edge_y)


def seat_plate(engine, k):
    """Put the finite plate k (a Disk or Segment facing down the vertical axis) at 1e-3
    of the smallest radius above the highest grain under it: a grain whose centre is at
    horizontal distance d [m] from the plate's footprint (0 under it, the distance to
    the rim beside it) and d < R_i first touches the plate at height
    z_i + sqrt(R_i^2 - d^2); grains farther out are left out (the free surface beside
    the plate).  d is the distance from the plate to the grain's centre brought to the
    plate's height (Walls.distances).  No grain under it: the plate goes above the
    highest grain (protocols.base.lower_onto_grains)."""
    s, walls = engine.state, engine.walls
    up = s.dim - 1
    k = walls.index(k)
    height = walls.geometry[k, up] + walls.offset[k, up]
    probes = s.positions.copy()
    probes[:, up] = height
    d, _ = walls.distances(probes, np.full(s.n, k))
    under = d < s.radii
    if not under.any():
        lower_onto_grains(engine, k)
        return
    top = s.positions[under, up] + np.sqrt(s.radii[under] ** 2 - d[under] ** 2)
    offset = walls.offset[k].copy()
    offset[up] = float(top.max()) + 1e-3 * float(s.radii.min()) - walls.geometry[k, up]
    engine.place_wall(k, offset)


def load_overlaps(run_dir):
    """{to_cycle: (before, after)}: every contact's overlap over the smaller radius [-]
    in each extrapolated configuration of a cyclic procedure and after its relaxation,
    from its relaxations/ folder (Cycles._save_overlaps)."""
    out = {}
    for f in sorted((pathlib.Path(run_dir) / RELAXATIONS).glob("to_cycle_*.npz")):
        with np.load(f) as data:
            out[int(f.stem.removeprefix("to_cycle_"))] = (data["before"], data["after"])
    if not out:
        raise FileNotFoundError(f"{run_dir}: no {RELAXATIONS}/to_cycle_*.npz")
    return out


def relaxation_figure(run_dir, title=""):
    """The distribution of the contacts' overlaps over the smaller radius before and
    after each relaxation of a cyclic procedure (Karrech et al.'s Fig. 9): one panel
    per extrapolation (at most four: the first ones and the last), histograms on
    logarithmic bins, the largest overlap of each marked."""
    from ..figures import subplots

    overlaps = load_overlaps(run_dir)
    jumps = list(overlaps)
    if len(jumps) > 4:
        jumps = jumps[:3] + jumps[-1:]
    values = np.concatenate([np.concatenate(overlaps[c]) for c in jumps])
    values = values[values > 0]
    low = max(float(values.min()), 1e-12) if values.size else 1e-6
    high = float(values.max()) if values.size else 1.0
    bins = np.geomspace(low, max(high, 1.01 * low), 40)
    fig, axes = subplots(1, len(jumps), figsize=(4.2 * len(jumps), 3.8), squeeze=False)
    for ax, cycle in zip(axes[0], jumps):
        for data, label, colour in ((overlaps[cycle][0], "extrapolated", "tab:red"),
                                    (overlaps[cycle][1], "relaxed", "tab:blue")):
            ax.hist(data[data > 0], bins=bins, histtype="step", color=colour,
                    label=f"{label}: {data.size} contacts, largest {data.max(initial=0):.2g}")
            if data.size:
                ax.axvline(data.max(), color=colour, ls=":", lw=1)
        ax.set(xscale="log", xlabel="overlap / smaller radius [-]",
               title=f"extrapolation to cycle {cycle}")
        ax.legend(fontsize=7, loc="upper left")
    axes[0][0].set_ylabel("contacts")
    fig.suptitle(f"{title}: overlaps before and after relaxation (Karrech Fig. 9)")
    return fig


def residual_cycles(run_dir):
    """The cycles (ascending) whose residual displacements a cyclic run wrote: every
    cycle, or with the procedure the computed ones and the ends of the extrapolations."""
    files = sorted((pathlib.Path(run_dir) / "residuals").glob("cycle_*.npy"))
    if not files:
        raise FileNotFoundError(f"{run_dir}: no residuals/cycle_*.npy")
    return [int(f.stem.removeprefix("cycle_")) for f in files]


def load_residuals(run_dir):
    """The residual displacements of a cyclic run, (cycles, N, 3) [m], in the order of
    residual_cycles, from its residuals/ folder."""
    folder = pathlib.Path(run_dir) / "residuals"
    return np.stack([np.load(folder / f"cycle_{c:06d}.npy") for c in residual_cycles(run_dir)])
