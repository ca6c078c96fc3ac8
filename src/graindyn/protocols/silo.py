"""The discharge of a 2D silo (Pérez Sec. 4): flow through a hole in the bottom,
re-injection of the disks that left, jamming, tapping and the statistics of avalanches.

The silo: the container's side walls (a 2D open-top box of width D) and a floor of two
segments with a hole of width d_h at its centre, closed during the preparation by a
third segment, the gate.  Phases:

* "settle" (protocols.phases.Settle): the disks on a loose lattice with random velocities
  relax under gravity until the largest speed is below ``threshold``;
* "discharge": the gate drops away (far below the silo) and the disks flow out.  Every
  ``check_every`` t0 (t0 = sqrt(d_ave/g), v0 = g t0) the phase

  - re-injects the disks whose centre is more than ``exit_depth`` d_ave below the floor:
    5.5 d_ave (``reinject_height``) above the surface of the dense packing, over the
    lowest column of the surface (columns one d_ave wide, the surface of a column the
    top of its highest disk that touches another disk or a wall; ties: the column
    nearest the centre) so that the free surface stays roughly flat, higher by one d_ave
    per disk placed there in the same check, and higher again until the disk overlaps
    no other; keeping its vertical velocity, its horizontal velocity and spin set to zero;
  - declares the silo jammed when the largest speed is below v0/c and no disk has left
    for c t0 (c = ``jam_factor``), ends the avalanche (the disks that left since the
    last tap: its size s, 0 for a null avalanche) and taps: every wall of the silo moves
    vertically as y = A sin(2 pi nu t) for half a period, then stops (``tap_start``:
    the disks start at rest, or with the walls' velocity, the whole material moving in
    parallel with the silo; ``tap_end``: the disks go on when the walls stop, or lose
    the walls' last velocity with them);

  until ``avalanches`` avalanches after the first (the initial discharge, kept apart)
  or ``max_time`` of simulated time.

Every disk is accounted for at all times: a disk is in the silo or in flight below the
floor until the check that re-injects it; none is ever removed.  The avalanches and the
progress of the phase are in its state, so a resumed run loses and double-counts none.
"""
import math
from dataclasses import replace
from typing import Literal

import numpy as np
from pydantic import model_validator

from ..analysis import avalanches
from ..analysis.arch import blocking_arch
from ..core.triggers import Periodic
from ..core.walls import Motion, Segment
from ..output.network import draw_network
from ..output.vtk import write_grains
from ..schema import Float, Int, described as _f
from .base import Protocol, ProtocolPhase, register, run_until, write_rows
from .deposition import save_figure
from .phases import SettleSettings, preparation

GATE = "gate"
FLOOR = ("floor_left", "floor_right")
SIDES = ("xlo", "xhi")


class SiloSettings(SettleSettings):
    """The 2D silo of Pérez Sec. 4 (defaults: his values in SI)."""

    kind: Literal["silo"] = "silo"
    insertion: Literal["random", "lattice"] = _f(
        "lattice", "disks on a loose lattice with random velocities (Pérez), or random")
    lattice_speed: Float = _f(0.1, "random initial speed on the lattice [m/s]; >= 0", ge=0)
    criterion: Literal["energy_ratio", "max_speed"] = _f(
        "max_speed", "the preparation relaxes until the largest speed is below threshold")
    threshold: Float = _f(2e-3, "largest speed ending the preparation [m/s] (about v0/100 "
                          "for d_ave = 5 mm); > 0", gt=0)
    max_time: Float = _f(2.0, "longest preparation [s] of simulated time; (0, 1e4]",
                         gt=0, le=1e4)
    hole: Float = _f(0.0175, "width d_h of the hole [m] (R = d_h/d_ave; 3.5 cm = R 3.5 "
                     "for d_ave = 5 mm); > 0", gt=0)
    exit_depth: Float = _f(1.3, "a disk whose centre is this many d_ave below the floor "
                           "has left [-]; > 0", gt=0)
    reinject_height: Float = _f(5.5, "height of re-injection above the surface [d_ave]; "
                                "> 0", gt=0)
    lip: Literal["round", "open"] = _f(
        "round", "how the floor meets a disk at the lips of the hole: round (the floor's "
        "end points touch a disk whose centre is over the hole, as the sharp corner of "
        "a rigid plate would), or open (the floor acts only on disks whose centre is "
        "over it: the hole lets through every disk whose centre is over it; "
        "core.walls.Segment ends)")
    jam_factor: Float = _f(8.0, "c: jammed when the largest speed < v0/c and no disk left "
                           "for c t0 [-]; > 1", gt=1)
    check_every: Float = _f(0.05, "interval of the exit and jam checks [t0]; (0, 1]", gt=0,
                            le=1)
    tap_amplitude: Float = _f(0.006, "tap amplitude A [m] (0.6 cm); > 0", gt=0)
    tap_frequency: Float = _f(8.0, "tap frequency nu [Hz]; > 0", gt=0)
    tap_start: Literal["walls", "parallel"] = _f(
        "parallel", "how a tap starts: the disks with the walls' velocity 2 pi nu A, the "
        "whole material moving in parallel with the silo (parallel, Pérez's words); or "
        "the walls alone, the floor striking the disks at rest (walls)")
    tap_end: Literal["walls", "parallel"] = _f(
        "walls", "how a tap ends: the walls stop and the disks go on as they move "
        "(walls); or every free disk's velocity changes as the walls' does when they stop "
        "(parallel: with tap_start parallel, the whole material follows both velocity "
        "jumps of the silo, as in the silo's own frame, where a tap is the smooth "
        "acceleration A (2 pi nu)^2 sin(2 pi nu t) alone)")
    avalanches: Int = _f(100, "avalanches to record after the first [-]; >= 1", ge=1)
    jam_pictures: Int = _f(10, "jammed configurations written (VTK with the arch marked "
                           "and a picture of the force network), the first ones [-]; >= 0",
                           ge=0)
    discharge_time: Float = _f(100.0, "longest discharge [s] of simulated time; > 0", gt=0)

    @model_validator(mode="after")
    def _open_silo(self):
        if self.hole <= 0:
            raise ValueError("protocol.hole must be > 0 [m]")
        return self


@register
class Silo(Protocol):
    """Discharge of a 2D silo with re-injection, jamming, tapping and avalanches."""

    kind = "silo"
    settings = SiloSettings
    summary = ("2D silo (Pérez Sec. 4): discharge through a hole, re-injection, jams "
               "broken by taps, avalanche statistics")
    summarize_sweep = staticmethod(avalanches.summarize_sweep)

    def __init__(self, settings, vessel):
        super().__init__(settings, vessel)
        # the floor is three segments: the settled bed's report measures from the
        # lowest disk and weighs no single wall
        self.phases = (*preparation(settings, replace(vessel, bottom_wall=None)),
                       Discharge(self))

    @classmethod
    def cross_check(cls, config):
        p, box, grains = config.protocol, config.walls.container, config.grains
        p.check_dim(config.run.dim)
        if config.run.dim != 2 or getattr(box, "kind", None) != "box" or not box.open_top:
            raise ValueError("the silo protocol needs run.dim = 2 and an open-top box "
                             "(its width is the silo's; its floor is replaced by two "
                             "segments with the hole)")
        width = box.hi[0] - box.lo[0]
        d = grains.diameter
        d_min = d.min if d.distribution == "uniform" else d.smallest()
        d_max = d.max if d.distribution == "uniform" else d.mean + 4 * d.std
        if p.hole >= width:
            raise ValueError(f"protocol.hole = {p.hole} m is not narrower than the silo "
                             f"(width {width} m)")
        if p.hole <= d_min:
            raise ValueError(f"protocol.hole = {p.hole} m is not wider than the smallest "
                             f"disk ({d_min} m): nothing could flow out")
        if width < p.hole + 2 * d_max:
            raise ValueError(f"the silo (width {width} m) leaves less than a disk of floor "
                             f"on each side of the hole ({p.hole} m)")
        mean = 0.5 * (d.min + d.max) if d.distribution == "uniform" else d.mean
        column = grains.count * mean**2 / (0.8 * width)       # a dense packing's height
        if column > box.hi[1] - box.lo[1]:
            raise ValueError(f"the silo (width {width} m, height {box.hi[1] - box.lo[1]} m) "
                             f"is too narrow for {grains.count} disks: they fill about "
                             f"{column:.3g} m; widen it or make it taller")

    def walls(self, container, material_index):
        """The side walls of the container and the floor: two segments beside the hole
        and the gate that closes it until the discharge."""
        v, hole = self.vessel, self.p.hole
        centre = 0.5 * (v.lo[0] + v.hi[0])
        y = v.floor
        floor = material_index(None)
        left, right = centre - 0.5 * hole, centre + 0.5 * hole
        kept = [w for w in container if w.name != v.bottom_wall]
        return kept + [
            Segment((v.lo[0], y), (left, y), floor, name=FLOOR[0], ends=self.p.lip),
            Segment((right, y), (v.hi[0], y), floor, name=FLOOR[1], ends=self.p.lip),
            Segment((left, y), (right, y), floor, name=GATE)]

    def results(self, engine, states):
        discharge = states["discharge"]
        return {"settle": states["settle"]["report"], **discharge.get("report", {})}

    def tables(self, rundir, results):
        """avalanches.csv: one row per avalanche (the first marked)."""
        rows = results.get("avalanches", [])
        keys = ["number", "first", "size", "start_s", "end_s", "duration_s", "flow_rate_per_s",
                "mass_flow_kg_per_s", "arch_size"]
        return [write_rows(rundir.path / "avalanches.csv", rows, keys)]

    def figures(self, rundir, series, results):
        """The histogram n(s) (Pérez Fig. 4), the normalized cumulative w(s) (Eq. 39,
        Fig. 5) and the disks that left against time."""
        from ..figures import subplots

        sizes = np.array([r["size"] for r in results.get("avalanches", [])
                          if not r["first"]], dtype=float)
        fig, ax = subplots(1, 3, figsize=(15, 4.2))
        positive = sizes[sizes > 0]
        if positive.size:
            ax[0].hist(positive, bins=max(1, min(40, positive.size // 3 + 1)))
            s, w = avalanches.cumulative(sizes)
            ax[1].semilogy(s, w, "o", ms=3)
        ax[0].set(xlabel="avalanche size s [disks]", ylabel="n(s)",
                  title=f"{np.sum(sizes == 0)} null avalanches not shown")
        ax[1].set(xlabel="s [disks]", ylabel="w(s) (Eq. 39)")
        rows = results.get("avalanches", [])
        if rows:
            ends = [r["end_s"] for r in rows]
            ax[2].step(ends, np.cumsum([r["size"] for r in rows]), where="post")
        ax[2].set(xlabel="t [s]", ylabel="disks that left [-]")
        fig.suptitle(f"{self.title}: 2D silo, R = {results.get('R', float('nan')):.2f}, "
                     f"<s> = {results.get('mean_size', float('nan')):.1f}")
        return [save_figure(fig, rundir, "silo.png")]


class Discharge(ProtocolPhase):
    """The discharge with re-injection, jam detection and taps (module docstring)."""

    name = "discharge"

    def duration(self):
        return self.p.discharge_time

    def scales(self, engine):
        """(d_ave [m], t0 [s], v0 [m/s]) of the disks in ``engine``."""
        d = 2.0 * float(np.mean(engine.state.radii))
        g = float(np.linalg.norm(engine.gravity))
        t0 = math.sqrt(d / g)
        return d, t0, g * t0

    def run(self, engine, state, *, every=(), between=None):
        p = self.p
        d, t0, v0 = self.scales(engine)
        if "avalanches" not in state:
            gate = engine.walls.index(GATE)
            engine.place_wall(gate, (0.0, -10.0 * (self.vessel.hi[0] - self.vessel.lo[0]),
                                     0.0))
            state.update(avalanches=[], current={"start_s": engine.time, "size": 0,
                                                 "first": True},
                         last_exit_s=engine.time, exited=0, tap_end_s=None,
                         jammed=False, end_time=engine.time + p.discharge_time)
        interrupted = []

        def check(engine):
            self.reinject(engine, state, d)
            if state["tap_end_s"] is None and self.is_jammed(engine, state, t0, v0):
                state["jammed"] = True

        def pause(engine):
            if between is not None and between(engine):
                interrupted.append(True)
                return True
            return state["jammed"]

        watch = [*every, (Periodic(time=p.check_every * t0), check)]
        while len(state["avalanches"]) <= p.avalanches and engine.time < state["end_time"]:
            if state["jammed"]:
                state["jammed"] = False
                arch = blocking_arch(engine, FLOOR[0], FLOOR[1])
                self.record_jam(engine, len(state["avalanches"]), arch)
                self.close_avalanche(engine, state, arch)
                if len(state["avalanches"]) <= p.avalanches:
                    self.tap(engine, state)
                continue
            if state["tap_end_s"] is not None:
                status = run_until(engine, state, "tap_end_s", 0.0, every=watch,
                                   between=pause)
                if status == "stopped" and interrupted:
                    return "stopped"
                if status == "done":
                    self.end_tap(engine, state)
                continue
            run_until(engine, state, "end_time", 0.0, every=watch, between=pause)
            if interrupted:
                return "stopped"
        if state["tap_end_s"] is not None:
            self.end_tap(engine, state)
        state["report"] = self.report(engine, state)
        return "done"

    # ------------------------------------------------------------------ the silo
    def silo_walls(self, engine):
        return [engine.walls.index(n) for n in (*SIDES, *FLOOR, GATE)]

    def floor_height(self, engine):
        k = engine.walls.index(FLOOR[0])
        return float(engine.walls.geometry[k, 1] + engine.walls.offset[k, 1])

    def reinject(self, engine, state, d):
        """Re-inject the disks below the exit depth (module docstring); counts them."""
        s = engine.state
        floor = self.floor_height(engine)
        gone = np.flatnonzero(s.positions[:, 1] < floor - self.p.exit_depth * d)
        if gone.size == 0:
            return
        lo, hi = self.vessel.lo[0], self.vessel.hi[0]
        columns = max(1, int((hi - lo) // d))
        width = (hi - lo) / columns
        touching = np.zeros(s.n, bool)
        contacts = engine.contacts()
        touching[contacts.i] = touching[contacts.j] = True
        touching[engine.wall_contacts().grain] = True
        inside = touching & (s.positions[:, 1] >= floor)
        inside[gone] = False
        top = np.full(columns, floor)
        column = np.clip(((s.positions[:, 0] - lo) // width).astype(int), 0, columns - 1)
        np.maximum.at(top, column[inside], (s.positions[:, 1] + s.radii)[inside])
        centre = 0.5 * (columns - 1)
        positions = s.positions[gone].copy()
        velocities = np.zeros_like(positions)
        placed = []
        for n, i in enumerate(gone):
            b = min(range(columns), key=lambda c: (top[c], abs(c - centre)))
            r = s.radii[i]
            x = min(max(lo + (b + 0.5) * width, lo + r), hi - r)
            y = top[b] + self.p.reinject_height * d
            while self._overlaps(s, gone, placed, positions, x, y, r, i):
                y += d
            positions[n, 0], positions[n, 1] = x, y
            velocities[n, 1] = s.velocities[i, 1]
            placed.append(n)
            top[b] += d
        engine.relocate(gone, positions, velocities)
        state["exited"] += int(gone.size)
        state["current"]["size"] += int(gone.size)
        state["last_exit_s"] = engine.time

    @staticmethod
    def _overlaps(s, gone, placed, positions, x, y, r, i):
        """True when a disk of radius r at (x, y) would overlap a disk of the silo (other
        than those being re-injected) or one placed before it in this check."""
        others = np.ones(s.n, bool)
        others[gone] = False
        dx = s.positions[others, 0] - x
        dy = s.positions[others, 1] - y
        if np.any(dx * dx + dy * dy < (s.radii[others] + r) ** 2):
            return True
        for n in placed:
            if (positions[n, 0] - x) ** 2 + (positions[n, 1] - y) ** 2 \
                    < (s.radii[gone[n]] + r) ** 2:
                return True
        return False

    def is_jammed(self, engine, state, t0, v0):
        """Largest speed below v0/c and no disk left for c t0 (Pérez Sec. 4)."""
        c = self.p.jam_factor
        if engine.time - state["last_exit_s"] < c * t0:
            return False
        v = engine.state.velocities
        return float(np.sqrt(np.max(np.einsum("ij,ij->i", v, v)))) < v0 / c

    def close_avalanche(self, engine, state, arch=()):
        """End the current avalanche at the jam: its size, duration, flow rates and the
        disks of the blocking arch (``arch``, indices)."""
        a = state["current"]
        mass = float(np.mean(engine.state.masses))
        duration = state["last_exit_s"] - a["start_s"] if a["size"] else 0.0
        rate = a["size"] / duration if duration > 0 else 0.0
        state["avalanches"].append({
            "number": len(state["avalanches"]), "first": a["first"], "size": a["size"],
            "start_s": a["start_s"], "end_s": engine.time, "duration_s": duration,
            "flow_rate_per_s": rate, "mass_flow_kg_per_s": rate * mass,
            "arch_size": len(arch), "arch": [int(i) for i in arch]})
        self.protocol.log(f"avalanche {len(state['avalanches']) - 1}: {a['size']} disks, "
                          f"jammed at t = {engine.time:.5g} s")

    def record_jam(self, engine, number, arch):
        """The jammed configuration of avalanche ``number`` with its arch marked, for the
        first ``jam_pictures`` jams: jams/jam_000003.vtu (point field "marked") and
        jams/jam_000003.png (the force network, output.network)."""
        folder = self.protocol.folder
        if folder is None or number >= self.p.jam_pictures:
            return
        folder = folder / "jams"
        folder.mkdir(exist_ok=True)
        write_grains(folder / f"jam_{number:06d}.vtu", engine.state, arch)
        draw_network(engine, folder / f"jam_{number:06d}.png", arch,
                     title=f"{self.protocol.title}: jam {number}, t = {engine.time:.4g} s, "
                     f"arch of {len(arch)} disks")

    def tap(self, engine, state):
        """Every wall of the silo moves as y = A sin(2 pi nu t) for half a period; with
        ``tap_start`` "parallel" every free disk starts with the walls' velocity
        2 pi nu A upwards (Engine.kick), so the floor does not strike the packing."""
        p = self.p
        if p.tap_start == "parallel":
            free = np.flatnonzero(engine.state.fixed == 0)
            engine.kick(free, (0.0, 2.0 * math.pi * p.tap_frequency * p.tap_amplitude, 0.0))
        state["tap_from"] = [engine.walls.offset[k].tolist() for k in self.silo_walls(engine)]
        for k in self.silo_walls(engine):
            engine.set_motion(k, Motion("sinusoid", direction=(0.0, 1.0, 0.0),
                                        amplitude=p.tap_amplitude,
                                        frequency=p.tap_frequency))
        state["tap_end_s"] = engine.time + 0.5 / p.tap_frequency
        state["current"] = {"start_s": engine.time, "size": 0, "first": False}

    def end_tap(self, engine, state):
        """Stop the walls back where the tap found them: the run ends at the first step
        end not before the half period, up to one step's travel past it.  With
        ``tap_end`` "parallel" every free disk loses the walls' velocity then,
        A 2 pi nu cos(2 pi nu (t - t_tap)) (about -2 pi nu A) upwards (Engine.kick)."""
        p = self.p
        if p.tap_end == "parallel":
            omega = 2.0 * math.pi * p.tap_frequency
            speed = p.tap_amplitude * omega * math.cos(
                omega * (engine.time - state["current"]["start_s"]))
            engine.kick(np.flatnonzero(engine.state.fixed == 0), (0.0, -speed, 0.0))
        for k, where in zip(self.silo_walls(engine), state["tap_from"]):
            engine.set_motion(k, Motion("fixed"))
            engine.place_wall(k, where)
        state["tap_end_s"] = None
        state["last_exit_s"] = max(state["last_exit_s"], engine.time)

    def report(self, engine, state):
        """The avalanches and their statistics (the first, the initial discharge, left
        out of the statistics)."""
        d, t0, v0 = self.scales(engine)
        rows = state["avalanches"]
        sizes = np.array([r["size"] for r in rows if not r["first"]], dtype=float)
        a = state["current"]
        duration = state["last_exit_s"] - a["start_s"]
        # the avalanche under way when the run ended (a hole too large to jam: the whole
        # discharge): no size of the statistics, but a flow rate
        running = {"first": a["first"], "size": a["size"], "start_s": a["start_s"],
                   "duration_s": duration,
                   "flow_rate_per_s": a["size"] / duration if duration > 0 else 0.0}
        flowing = [r for r in (*rows, running) if r["size"] > 0 and r["duration_s"] > 0]
        out = {"R": self.p.hole / d, "d_ave_m": d, "t0_s": t0, "v0_m_per_s": v0,
               "g_m_per_s2": float(np.linalg.norm(engine.gravity)),
               "avalanches": rows, "unfinished": running, "count": int(sizes.size),
               "null_avalanches": int(np.sum(sizes == 0)),
               "exited": state["exited"], "time_s": engine.time}
        stats = avalanches.statistics(sizes)
        if sizes.size:
            out.update(mean_size=stats["mean"], mean_size_err=stats["mean_err"],
                       null_fraction=stats["null_fraction"])
        if flowing:            # disks per second over the time the silo flowed
            out["mean_flow_rate_per_s"] = float(
                sum(r["size"] for r in flowing) / sum(r["duration_s"] for r in flowing))
        return out
