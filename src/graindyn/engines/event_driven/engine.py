"""EventDriven: hard spheres (3D) or disks (2D) moved collision by collision (event-driven
molecular dynamics, Pérez Sec. 2), behind the engine interface of core/engine.py.

>>> engine = EventDriven(state, [Material(restitution=0.9)], periodic=[Periodic(0, 0, L),
...                      Periodic(1, 0, L), Periodic(2, 0, L)], gravity=(0, 0, 0))
...                                                                     # doctest: +SKIP
>>> engine.run(time=1.0); engine.collisions, engine.energies()["kinetic"]  # doctest: +SKIP

Grains fly freely between instantaneous binary collisions (collision.py, Pérez Eq.
1-10); the compiled loop of events.py carries out one event after the other from the
calendar of calendar.py.  Between pauses no Python runs; at a pause every grain is
brought to the pause's time, the walls are put where their motion has them then, and
the events are predicted afresh from there when the run goes on.

Hard grains touch only at instants, so the engine has no lasting contacts: ``contacts``
and ``wall_contacts`` are the pairs in touch at the pause (within the tolerance), and
they carry zero force.  What the collisions transmit is in the mean wall forces
(``walls.force``: the grains' impulse on each wall since the previous pause over its
duration) and in the collision virial (``virial``), from which the pressure of a gas
follows (analysis/gas.py).  A grain that comes to rest on a wall or a held grain under
gravity keeps hopping on it by the tolerance (events.py, least rebound; by g t_c^2/8
under the TC model), so a deposited bed ends as a bed of grains hopping on each other.
Walls that need lasting contact forces to move (servo and piston walls) are not
offered.
"""
import math

import numpy as np

from ...core.engine import (Contacts, SimulationError, WallContacts, checked_gravity,
                            copy_into)
from ...core.species import Material
from ...core.triggers import NO_CONDITION, pauses
from ...core.walls import PISTON, SERVO, Walls
from ..rigid import CONDITION, NAN, RigidGrains, stop_status
from . import events as ev
from .bundles import Cells, Grains, Tables, WallBundle
from .calendar import calendar_for
from .collision import COLLAPSE
from .flight import wall_displacement

# the per-grain arrays of the engine (beyond core.state.State's), saved in a snapshot
# grains in a neighbourhood of 3^dim cells, on average, when the cells are wider than a
# diameter: fewer cells mean fewer crossings but more pairs looked at per prediction
# (measured on elastic gases at packing fractions 0.05 and 0.3, BENCHMARKS.md)
NEIGHBOURHOOD_GRAINS = 5.0
_GRAIN_ARRAYS = ("collisions", "last_collision")


def restitution_table(materials):
    """(M, M) normal restitution e_n of each pair of materials: the geometric mean of
    theirs (None: 1, elastic), as core/species.py mixes them."""
    e = np.array([1.0 if m.restitution is None else m.restitution for m in materials])
    if np.any((e < 0) | (e > 1)):
        raise ValueError(f"restitution must be in [0, 1], got {e.tolist()}")
    return np.sqrt(np.outer(e, e))


class EventDriven(RigidGrains):
    """Hard grains by event-driven molecular dynamics (Pérez Sec. 2, Eq. 1-10), SI units.

    state : core.state.State;  materials : list of core.species.Material (restitution
      e_n in [0, 1], None = 1; the rest unused);  walls : Plane/Cylinder/Segment list
      (fixed, "velocity" or "sinusoid" motion); periodic : Periodic list;
      gravity (3,) [m/s^2]
    tangential_restitution e_s [-] in [-1, 1] (Pérez Eq. 6): +1 smooth grains (no
      tangential impulse), -1 perfectly rough ones, 0 the contact points stop sliding
    collapse : "none", "speed" or "tc" (collision.restitution_now): the treatment of
      inelastic collapse;  collapse_speed [m/s] (u0 of "speed");  contact_duration [s]
      (t_c of "tc")
    tolerance [-]: a grain closer to a wall than this fraction of its radius, and
      approaching it, collides (the walls met by conservative advancement, flight.py);
      grains found overlapping more than it at a pause stop the run
    sync_interval [s]: the longest stretch of simulated time between pauses of a run
      with a stop condition (the condition is tested at pauses); None: 1/100 of the run.

    Counters: ``collisions`` (grain pairs), ``wall_collisions``, ``events`` (all events,
    cell crossings and stale ones included); ``step`` is ``events``.
    """

    GRAVITY_SLOTS = ev.GX
    LOSS_SLOTS = (ev.DISS_N, ev.DISS_T, ev.WALL_WORK)

    rigid = True        # hard grains (engine.Engine.rigid)

    def __init__(self, state, materials, walls=(), periodic=(), gravity=(0.0, 0.0, -9.81),
                 tangential_restitution=1.0, collapse="none", collapse_speed=None,
                 contact_duration=None, tolerance=1e-9, sync_interval=None):
        self.state = state
        self.materials = list(materials) if materials else [Material()]
        n_mat = len(self.materials)
        if state.materials.size and (state.materials.min() < 0
                                     or state.materials.max() >= n_mat):
            raise ValueError(f"grain material ids must be in 0..{n_mat - 1}")
        self.walls = walls if isinstance(walls, Walls) else Walls(walls, periodic)
        if np.any(self.walls.material >= n_mat):
            raise ValueError(f"wall material ids must be in 0..{n_mat - 1}")
        for k in range(len(self.walls)):
            self._check_motion(k, self.walls.motion_kind[k])
        for wall in self.walls.walls:
            if getattr(wall, "ends", "round") != "round":
                raise ValueError(
                    f"wall {wall.name!r}: a segment with open ends touches a grain only "
                    "while its centre is over it, a gap that jumps; the event-driven "
                    "engine predicts collisions from a gap that changes continuously "
                    "(use round ends, or the soft or contact dynamics engine)")
        if collapse not in COLLAPSE:
            raise ValueError(f"collapse must be one of {sorted(COLLAPSE)}, got {collapse!r}")
        if collapse == "speed" and not (collapse_speed is not None and collapse_speed > 0):
            raise ValueError("collapse = 'speed' needs collapse_speed > 0 [m/s]")
        if collapse == "tc" and not (contact_duration is not None and contact_duration > 0):
            raise ValueError("collapse = 'tc' needs contact_duration > 0 [s]")
        if not -1.0 <= tangential_restitution <= 1.0:
            raise ValueError(f"tangential_restitution must be in [-1, 1], got "
                             f"{tangential_restitution}")
        if not (0 < tolerance < 1e-3):
            raise ValueError(f"tolerance must be in (0, 1e-3), got {tolerance}")
        if sync_interval is not None and not sync_interval > 0:
            raise ValueError(f"sync_interval must be > 0 [s], got {sync_interval}")
        for d in range(3):
            if self.walls.periodic_flag[d] and \
                    self.walls.periodic_length[d] <= 4 * state.radii.max():
                raise ValueError(f"periodic length along axis {d} must exceed twice the "
                                 "largest diameter")
        self.tables = Tables(restitution_table(self.materials))
        self.sync_interval = sync_interval
        self.clock = np.zeros(ev.NCLOCK)
        self.clock[ev.TIME] = state.time
        self.clock[ev.GX:ev.GZ + 1] = checked_gravity(gravity, state.dim)
        self.clock[ev.TANGENTIAL] = tangential_restitution
        self.clock[ev.COLLAPSE_SPEED] = collapse_speed or 0.0
        self.clock[ev.CONTACT_DURATION] = contact_duration or 0.0
        self.clock[ev.TOLERANCE] = tolerance
        self.counters = np.zeros(ev.NCOUNTERS, np.int64)
        self.counters[ev.EVENTS] = state.step
        self.counters[ev.COLLAPSE_MODEL] = COLLAPSE[collapse]
        n = state.n
        self.collision_counts = np.zeros(n, np.int64)
        self.last_collision = np.full(n, -math.inf)
        self.local_time = np.full(n, state.time)
        self._wall_impulse = np.zeros((len(self.walls), 3))
        self._calendar = calendar_for(n)
        self._place_walls()

    def _check_motion(self, k, kind):
        if kind in (SERVO, PISTON):
            raise ValueError(
                f"wall {self.walls.walls[k].name!r}: servo and piston walls move by the "
                "force of lasting contacts, which hard grains do not have; the "
                "event-driven engine offers fixed, velocity and sinusoid walls (use the "
                "soft engine for a stress-controlled test)")

    # ------------------------------------------------------------------ bundles
    def _grains(self):
        s = self.state
        return Grains(s.positions, s.velocities, s.angular_velocities, s.orientations,
                      s.radii, s.masses, s.inertias, s.materials, s.fixed, self.local_time,
                      self.collision_counts, self.last_collision,
                      self.clock[ev.GX:ev.GZ + 1])

    def _walls(self):
        w = self.walls
        return WallBundle(w.kind, w.geometry, w.base, w.motion_kind, w.motion, w.material,
                          self._wall_impulse)

    def _box(self):
        return self.walls.periodic_box()

    def _cells(self):
        """The cell grid of the grains as they are: cells at least a largest diameter
        wide, the period divided evenly along periodic axes, the grains' extent along
        the others (the outermost cells reaching to infinity), at most about
        3^dim N / NEIGHBOURHOOD_GRAINS + 8 cells in all."""
        s = self.state
        w = self.walls
        dims = s.dim
        side = 2.0 * float(s.radii.max())
        lo = np.zeros(3)
        extent = np.zeros(3)
        for d in range(dims):
            if w.periodic_flag[d]:
                lo[d], extent[d] = w.periodic_lo[d], w.periodic_length[d]
            else:
                lo[d] = float(s.positions[:, d].min())
                extent[d] = float(s.positions[:, d].max()) - lo[d]
        counts = np.ones(3, np.int64)
        while True:
            for d in range(dims):
                counts[d] = max(1, int(extent[d] // side))
            if counts.prod() <= 3**dims * s.n / NEIGHBOURHOOD_GRAINS + 8:
                break
            side *= 1.25
        size = np.where(counts > 0, extent / counts, side)
        size[size <= 0] = side
        for d in range(dims):
            if not w.periodic_flag[d]:
                size[d] = max(size[d], side)
        n = s.n
        return Cells(lo, size, counts, np.zeros(n, np.int64), np.zeros((n, 3), np.int64),
                     np.full(int(counts.prod()), -1, np.int64), np.full(n, -1, np.int64),
                     np.full(n, -1, np.int64))

    # ------------------------------------------------------------------ running
    @property
    def time(self):
        """Simulated time [s]."""
        return float(self.clock[ev.TIME])

    @property
    def step(self):
        """Events carried out since the start (collisions, cell crossings, stale events)."""
        return int(self.counters[ev.EVENTS])

    events = step

    @property
    def collisions(self):
        """Grain-grain collisions since the start."""
        return int(self.counters[ev.PAIR_COLLISIONS])

    @property
    def wall_collisions(self):
        """Grain-wall collisions since the start."""
        return int(self.counters[ev.WALL_COLLISIONS])

    @property
    def virial(self):
        """The collision virial since the start, sum over collisions of (r_i - r_j) . J_i
        [J s] (J_i the impulse on grain i): the pressure of a gas of volume V over a
        time T is P = (N k T_g + virial / (d T)) / V (analysis/gas.py)."""
        return float(self.clock[ev.VIRIAL])

    def _place_walls(self):
        """Walls' offset and velocity where their motion has them at the present."""
        w = self.walls
        for k in range(len(w)):
            shift = wall_displacement(w.motion_kind, w.motion, k, self.time)
            w.offset[k] = w.base[k] + np.array(shift[:3])
            w.velocity[k] = shift[3:]

    def _prepare(self):
        """Grains binned, checked for overlaps, every event predicted (the start of a
        stretch of events)."""
        self._bin()
        g = self._grains()
        i, j, gap = ev.close_pairs(g, self._cell_grid, self._box(), -self._overlap_limit())
        if i.size:
            k = int(np.argmin(gap))
            raise SimulationError(
                f"grains {i[k]} and {j[k]} overlap by {-gap[k]:.3g} m at t = "
                f"{self.time:.6g} s: hard grains must start apart (insert them without "
                "overlaps)")
        ev.predict_all(g, self._calendar, self._cell_grid, self._walls(), self._box(),
                       self.clock)

    def _bin(self):
        """Every grain brought to the present and put in the cells of a new grid."""
        self._cell_grid = self._cells()
        self.local_time[:] = self.time
        ev.bin_grains(self._grains(), self._cell_grid, self._box())

    def _overlap_limit(self):
        """The overlap [m] beyond which grains found at a pause stop the run: a thousand
        times the tolerance of the smallest radius (round-off leaves far less)."""
        return 1e3 * self.clock[ev.TOLERANCE] * float(self.state.radii.min())

    def _stretch(self, end):
        """Every event up to ``end`` [s]; the grains brought there, the walls placed."""
        start = self.time
        self._prepare()
        self._wall_impulse[:] = 0.0
        status = ev.run_events(self._grains(), self._calendar, self._cell_grid,
                               self._walls(), self._box(), self.tables, self.clock,
                               self.counters, end, self._straight())
        if status == ev.COLLAPSED:
            ev.synchronise(self._grains(), self.time, start)
            self.state.time = self.time
            raise SimulationError(
                f"inelastic collapse at t = {self.time:.9g} s: {ev.SAME_TIME_LIMIT} "
                "collisions at one instant, a cluster whose collisions never end (a "
                "collapse: choose collapse = 'tc' or 'speed'), or touching rough grains "
                "that a wall drives at once (choose collapse = 'tc' or 'speed': their "
                "simultaneous collisions are smooth)")
        ev.synchronise(self._grains(), end, start)
        self.clock[ev.TIME] = end
        self.state.time = end
        self.state.step = self.step
        self._place_walls()
        if end > start:
            self.walls.force[:] = self._wall_impulse / (end - start)

    def _straight(self):
        """Whether the grains fly on straight lines and none is held (no gravity): the
        event loop then runs its copy without those terms (events.run_events)."""
        return np.bool_(not self.clock[ev.GX:ev.GZ + 1].any() and not self.state.fixed.any())

    def run(self, time=None, until=None, every=(), between=None):
        """Advance the simulated time by ``time`` [s] (engine.Engine.run: the run ends at
        exactly that time, or earlier at a pause where ``until`` (MaxSpeedBelow,
        EnergyRatioBelow, tested at every pause) holds).  ``every``: (trigger,
        callback(engine)) pairs, the triggers' Periodic(time=...) falling at multiples
        of their period; ``between``: callback(engine) at every pause, True stops the
        run.  Returns "done", "condition" or "stopped"; SimulationError on inelastic
        collapse or non-finite values."""
        if time is None:
            raise ValueError("run needs time= (an upper bound, also with until=)")
        if not time >= 0:
            raise ValueError(f"time must be >= 0 [s], got {time}")
        periods = {}
        for trigger, _ in every:
            for p in pauses(trigger):
                if p.time is None:
                    raise ValueError("the event-driven engine pauses by simulated time: "
                                     "give Periodic(time=...), not steps")
                periods[p] = p.time
        end = self.time + time
        interval = self.sync_interval or (time / 100 if until is not None else math.inf)
        kind = until.kind if until is not None else NO_CONDITION
        while self.time < end:
            target = min(end, self.time + interval)
            for period in periods.values():
                target = min(target, (math.floor(self.time / period + 1e-9) + 1) * period)
            self._stretch(target)
            due = {p: abs(self.time / t - round(self.time / t)) < 1e-9
                   for p, t in periods.items()}
            for trigger, cb in every:
                if trigger.fires(lambda p: due[p], self.time):
                    cb(self)
            s = self.state
            status = stop_status(s.velocities, s.angular_velocities, s.positions, s.masses,
                                 s.inertias, s.fixed, self.clock[ev.GX:ev.GZ + 1], kind,
                                 until.value if until is not None else 0.0)
            if status == NAN:
                raise SimulationError(f"non-finite position or velocity at t = "
                                      f"{self.time:.6g} s")
            if status == CONDITION:
                return "condition"
            if between is not None and between(self):
                return "stopped"
        return "done"

    # ------------------------------------------------------------------ snapshots
    def _arrays(self):
        arrays = {f"grains/{k}": v for k, v in self.state.arrays().items()}
        arrays.update({"grains/collisions": self.collision_counts,
                       "grains/last_collision": self.last_collision,
                       "walls/offset": self.walls.offset, "walls/base": self.walls.base,
                       "walls/velocity": self.walls.velocity,
                       "walls/force": self.walls.force,
                       "walls/motion_kind": self.walls.motion_kind,
                       "walls/motion": self.walls.motion,
                       "loop/clock": self.clock, "loop/counters": self.counters})
        return arrays

    def snapshot(self):
        """Every mutable array of the run by name (copies): grains with their collision
        counters and last collision times, walls, clock and counters; ``restore`` of it
        continues the run bit for bit (the events are predicted afresh from the
        synchronised grains at every pause)."""
        return {k: np.array(v, copy=True) for k, v in self._arrays().items()}

    def restore(self, arrays):
        """Put a ``snapshot`` back (an engine built from the same inputs); ValueError
        naming what is missing or does not fit."""
        copy_into(self._arrays(), arrays)
        self.state.time = self.time
        self.state.step = self.step

    # ------------------------------------------------------------------ contacts
    def contacts(self):
        """The grain pairs in touch now (gap within the tolerance of the smaller radius),
        engine.Contacts with zero force (hard grains touch at instants; module
        docstring); the normal from j to i, the contact point on the line of centres."""
        s = self.state
        self._bin()
        i, j, gap = ev.close_pairs(self._grains(), self._cell_grid, self._box(),
                                   self.clock[ev.TOLERANCE] * float(s.radii.max()))
        r_i, r_j = s.radii[i], s.radii[j]
        keep = gap <= self.clock[ev.TOLERANCE] * np.minimum(r_i, r_j)
        i, j, r_i, r_j = i[keep], j[keep], r_i[keep], r_j[keep]
        separation = self.walls.minimum_image(s.positions[i] - s.positions[j])
        share = (r_i / (r_i + r_j))[:, None]
        normal = separation / np.linalg.norm(separation, axis=1)[:, None]
        return Contacts(i, j, -share * separation, (1.0 - share) * separation,
                        np.zeros(i.size), np.zeros((i.size, 3)), normal)

    def wall_contacts(self):
        """The grain-wall pairs in touch now (gap within the tolerance of the radius),
        engine.WallContacts with zero force (module docstring)."""
        s = self.state
        grains, walls = [], []
        for k in range(len(self.walls)):
            ids = np.full(s.n, k)
            distance, _ = self.walls.distances(s.positions, ids)
            near = np.flatnonzero(distance - s.radii <= self.clock[ev.TOLERANCE] * s.radii)
            grains.append(near)
            walls.append(np.full(near.size, k, np.int64))
        grain = np.concatenate(grains) if grains else np.zeros(0, np.int64)
        wall = np.concatenate(walls) if walls else np.zeros(0, np.int64)
        distance, normal = self.walls.distances(s.positions[grain], wall)
        return WallContacts(grain.astype(np.int64), wall, -distance[:, None] * normal,
                            np.zeros(grain.size), np.zeros((grain.size, 3)), normal)

    # ------------------------------------------------------------------ changes by hand
    def relocate(self, indices, positions, velocities, angular_velocities=None):
        """Move grains ``indices`` to ``positions`` (K, 3) [m] with ``velocities`` (K, 3)
        [m/s] and ``angular_velocities`` (K, 3) [rad/s] (None: zero)
        (engine.Engine.relocate); hard grains carry no contact memory, and the next run
        predicts every event afresh."""
        self.state.move(indices, positions, velocities, angular_velocities)

    def set_motion(self, wall, motion):
        """Prescribe ``motion`` (walls.Motion) to ``wall`` from now on
        (engine.Engine.set_motion); servo and piston motion are refused (ValueError)."""
        k = self.walls.index(wall)
        self._check_motion(k, motion.row()[0])
        self.walls.prescribe(k, motion, self.time)
        self._place_walls()

    def set_servo(self, wall, **settings):
        """Servo walls are not offered: hard grains have no lasting contact force for
        them to balance (ValueError)."""
        self._check_motion(self.walls.index(wall), SERVO)

    def place_wall(self, wall, offset):
        """Put ``wall`` at ``offset`` (3,) [m] from where it was built, at once
        (engine.Engine.place_wall)."""
        self.walls.place(wall, offset)
        self._place_walls()
