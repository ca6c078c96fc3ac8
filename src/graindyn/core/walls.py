"""Walls and boundaries: planes, axis-aligned boxes, the inside of a cylinder, finite
segments (2D) and rectangles (3D), disks (3D), periodic directions; prescribed wall
motion.  Walls
are geometry only: their contact forces come from the same
physics.contact.contact_force as grain pairs, with R_j = infinity.

Kernel layout (``Walls.arrays``): kind (W,) 0 plane / 1 cylinder inside / 2 segment /
3 disk; geometry (W, 10) (GEOMETRY_WIDTH): plane: origin (3), unit normal (3), 0, 0 0 0;
cylinder: a point of the axis (3), unit axis (3), radius [m], 0 0 0; segment: start
(corner) (3), first edge end - start (3) [m], 1 for open ends else 0, second edge (3)
[m] (0 0 0 for a line segment); disk: centre (3), unit normal (3), radius [m], 0 0 0; motion_kind (W,)
0 fixed / 1 constant velocity / 2 sinusoid / 3 servo / 4 piston; motion (W, 9)
(MOTION_WIDTH) = unit direction (3), then speed [m/s], amplitude [m], frequency [Hz],
phase [rad] (velocity, sinusoid) or target force [N], gain [m/(N s)], largest speed
[m/s], unused (servo) or mean force [N], force amplitude [N], frequency [Hz], phase
[rad] (piston), the start time [s], and the piston's mass [kg] (0 for the others);
offset (W, 3) [m] and velocity (W, 3) [m/s] of each wall (state).

The servo is a stress-controlled wall: a velocity servo on the force the grains exert
against its direction of motion u, from the previous force evaluation,
    v = clamp(g (F_target - F), -v_max, v_max),   F = -force . u,
so the force error decays as exp(-t K g) when the sample in front of the wall has
stiffness K [N/m].  With g <= 1/(K tau) the wall closes the error no faster than the
time constant tau and, having no inertia, cannot overshoot by itself; the protocol that
uses it (protocols/oedometer.py) sets g from the stiffness of the wall's contacts.

The piston is a rigid wall of mass M driven along u by an applied force and by the
grains: the loading plate of a load-controlled test (a weight falling on the sample,
Oquendo et al.'s top wall that "falls down with the initial pressure p0", or Karrech et
al.'s plate under a cyclic stress), with the inertia a velocity servo lacks,

    M ds/dt = F_applied(t) - F,   F_applied(t) = F_mean + F_amp sin(2 pi f (t - t_start) + phase),

s = v . u its speed into the grains, F = -force . u as above.  Its own weight is not
added: put it in F_mean.  Semi-implicit Euler with the force of the last evaluation
(s += dt (F_applied(t) - F) / M, then x += s u dt), first order as the servo, stable for
dt below 2 sqrt(M / K) against contacts of stiffness K, far above a grain step when M
is a few grain masses or more.
"""
import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from .._jit import scalar, kernel

PLANE, CYLINDER, SEGMENT, DISK = 0, 1, 2, 3
SEGMENT_ENDS = ("round", "open")       # Segment.ends
GEOMETRY_WIDTH = 10        # columns of Walls.geometry (module docstring)
FIXED, VELOCITY, SINUSOID, SERVO, PISTON = 0, 1, 2, 3, 4
MOTION_WIDTH = 9           # columns of Walls.motion (module docstring)


def _unit(v, what):
    v = np.asarray(v, dtype=np.float64)
    if v.shape != (3,) or not np.all(np.isfinite(v)) or np.linalg.norm(v) == 0:
        raise ValueError(f"{what} must be a finite non-zero 3-vector, got {v}")
    return v / np.linalg.norm(v)


@dataclass(frozen=True)
class Motion:
    """Prescribed wall motion.

    kind "fixed"; "velocity": x(t) = x0 + velocity (t - start) [m/s];
    "sinusoid": x(t) = x0 + direction amplitude (sin(2 pi f (t-start) + phase) - sin(phase));
    "servo": moves along ``direction`` (into the grains) at
    clamp(gain (force - F), -max_speed, max_speed) where F [N] is the force the grains
    exert against ``direction``, ``force`` the target [N], ``gain`` [m/(N s)];
    "piston": a wall of ``mass`` [kg] pushed along ``direction`` by
    force + force_amplitude sin(2 pi frequency (t - start) + phase) [N] and held back by
    F (module docstring); it starts with the wall's velocity along ``direction``.
    """

    kind: str = "fixed"
    velocity: tuple = (0.0, 0.0, 0.0)
    direction: tuple = (0.0, 0.0, 1.0)
    amplitude: float = 0.0
    frequency: float = 0.0
    phase: float = 0.0
    start: float = 0.0
    force: float = 0.0
    gain: float = 0.0
    max_speed: float = 0.0
    force_amplitude: float = 0.0
    mass: float = 0.0

    def row(self):
        """(kind id, (MOTION_WIDTH,) parameters) for the kernel."""
        row = np.zeros(MOTION_WIDTH)
        row[7] = self.start
        if self.kind == "fixed":
            return FIXED, np.zeros(MOTION_WIDTH)
        if self.kind == "velocity":
            v = np.asarray(self.velocity, dtype=np.float64)
            speed = float(np.linalg.norm(v))
            u = v / speed if speed > 0 else np.zeros(3)
            row[:4] = *u, speed
            return VELOCITY, row
        if self.kind == "sinusoid":
            if self.amplitude < 0 or self.frequency <= 0:
                raise ValueError("sinusoid motion needs amplitude >= 0 and frequency > 0 [Hz]")
            row[:7] = *_unit(self.direction, "motion direction"), 0.0, self.amplitude, \
                self.frequency, self.phase
            return SINUSOID, row
        if self.kind == "servo":
            if self.force < 0 or self.gain < 0 or not self.max_speed > 0:
                raise ValueError("servo motion needs force >= 0 [N], gain >= 0 [m/(N s)] and "
                                 "max_speed > 0 [m/s]")
            row[:6] = *_unit(self.direction, "motion direction"), self.force, self.gain, \
                self.max_speed
            return SERVO, row
        if self.kind == "piston":
            numbers = (self.force, self.force_amplitude, self.frequency, self.phase)
            if not (self.mass > 0 and math.isfinite(self.mass)) or self.force_amplitude < 0 \
                    or self.frequency < 0 or not all(math.isfinite(x) for x in numbers):
                raise ValueError("piston motion needs mass > 0 [kg], a finite force [N], "
                                 "force_amplitude >= 0 [N] and frequency >= 0 [Hz]")
            row[:7] = *_unit(self.direction, "motion direction"), *numbers
            row[8] = self.mass
            return PISTON, row
        raise ValueError(f"unknown wall motion {self.kind!r}; choose fixed, velocity, "
                         "sinusoid, servo, piston")

    @classmethod
    def from_row(cls, kind, row):
        """The Motion of kernel row ``row`` (MOTION_WIDTH,) of kind id ``kind`` (the
        inverse of row)."""
        u, start = tuple(float(x) for x in row[:3]), float(row[7])
        if kind == VELOCITY:
            return cls("velocity", velocity=tuple(float(x * row[3]) for x in row[:3]),
                       start=start)
        if kind == SINUSOID:
            return cls("sinusoid", direction=u, amplitude=float(row[4]),
                       frequency=float(row[5]), phase=float(row[6]), start=start)
        if kind == SERVO:
            return cls("servo", direction=u, force=float(row[3]), gain=float(row[4]),
                       max_speed=float(row[5]), start=start)
        if kind == PISTON:
            return cls("piston", direction=u, force=float(row[3]),
                       force_amplitude=float(row[4]), frequency=float(row[5]),
                       phase=float(row[6]), mass=float(row[8]), start=start)
        return cls()


@dataclass
class Plane:
    """Infinite plane through ``point`` [m]; grains live on the side ``normal`` points to.

    area [m^2] is used to turn the wall force into a stress (None: unknown).
    """

    point: tuple
    normal: tuple
    material: int = 0
    motion: Motion = field(default_factory=Motion)
    name: str = "plane"
    area: float | None = None

    def row(self):
        return PLANE, np.array([*np.asarray(self.point, float), *_unit(self.normal, "normal"),
                                0.0])


@dataclass
class Cylinder:
    """Inside of a cylinder of ``radius`` [m] around the axis through ``point`` along ``axis``."""

    point: tuple
    axis: tuple
    radius: float
    material: int = 0
    motion: Motion = field(default_factory=Motion)
    name: str = "cylinder"
    area: float | None = None

    def row(self):
        if not self.radius > 0:
            raise ValueError(f"cylinder radius must be > 0 [m], got {self.radius}")
        return CYLINDER, np.array([*np.asarray(self.point, float), *_unit(self.axis, "axis"),
                                   float(self.radius)])


def _point(v, what):
    """A finite point or vector [m] of 2 (x, y; z = 0) or 3 components, as a 3-vector."""
    v = np.asarray(v, dtype=np.float64)
    if v.shape not in ((2,), (3,)) or not np.all(np.isfinite(v)):
        raise ValueError(f"{what} must be a finite vector of 2 or 3 components [m], got {v}")
    return np.append(v, 0.0) if v.size == 2 else v


@dataclass
class Segment:
    """A finite wall: a thin rigid plate, which grains touch from either side.

    2D: the line segment from ``start`` to ``end`` [m] in the x-y plane (z = 0; two
    components may be given).  3D: with ``edge`` [m] non-zero, the rectangle with corners
    start, end, end + edge, start + edge, i.e. spanned by the edges end - start and
    ``edge``, which must be perpendicular.  (``edge`` zero in 3D: a thin rod.)

    Contact: the distance is from the grain centre to the closest point of the segment
    (rectangle), edges and end points (corners) included, and the normal points from that
    point to the centre.  So the wall is two-sided, of zero thickness, and rounded at its
    ends: a grain at the lip of an orifice between two segments touches the end point,
    with the normal along the line from the end point to its centre, and a grain passes
    a gap between two segments wider than its diameter.  Like a plate of any thickness,
    it holds grains only while their overlap stays below their radius: a grain driven
    through its middle comes out on the other side.

    ends: "round" (the contact above) or "open": the wall then acts only on grains whose
    centre lies over it (its projection on the segment's line, the rectangle's plane,
    falls inside the segment or rectangle), at the distance to that projection; a grain
    whose centre is beyond an end or edge does not touch it at all, however deep it
    reaches over it.  A hole between two open-ended segments lets through any grain whose
    centre is over the hole: a floor written as "y = 0 wherever there is floor", as a
    code without segments would write it.  The event-driven engine, whose collision
    times need the gap to change continuously, refuses it.

    area [m^2] (2D: length [m] per unit depth) turns the wall force into a stress:
    |end - start| (2D) or |end - start| |edge| (3D) when None.  The normal force
    (Walls.normal_force) is the magnitude of the force of the grains on it, as for the
    cylinder: a two-sided wall has no inward normal.
    """

    start: tuple
    end: tuple
    material: int = 0
    motion: Motion = field(default_factory=Motion)
    name: str = "segment"
    area: float | None = None
    edge: tuple = (0.0, 0.0, 0.0)
    ends: str = "round"

    def __post_init__(self):
        if self.ends not in SEGMENT_ENDS:
            raise ValueError(f"segment {self.name!r}: ends must be one of {SEGMENT_ENDS}, "
                             f"got {self.ends!r}")
        a, b = self._edges()
        if self.area is None:
            la = float(np.linalg.norm(a))
            self.area = la if not b.any() else la * float(np.linalg.norm(b))

    def _edges(self):
        start = _point(self.start, "segment start")
        a = _point(self.end, "segment end") - start
        b = _point(self.edge, "segment edge")
        la, lb = np.linalg.norm(a), np.linalg.norm(b)
        if la == 0:
            raise ValueError(f"segment {self.name!r}: start and end coincide ({start})")
        if lb > 0 and abs(a @ b) > 1e-9 * la * lb:
            raise ValueError(f"segment {self.name!r}: edge {b} must be perpendicular to "
                             f"end - start {a} (the wall is a rectangle)")
        return a, b

    def row(self):
        a, b = self._edges()
        return SEGMENT, np.array([*_point(self.start, "segment start"), *a,
                                  float(self.ends == "open"), *b])


@dataclass
class Disk:
    """A flat circular plate (3D): the disk of ``radius`` [m] centred at ``center`` [m]
    in the plane normal to ``normal``, a thin rigid plate which grains touch from either
    side (the loading plate of a cylinder that covers only part of its top).

    Contact: as for a Segment's rectangle, the distance is from the grain centre to the
    closest point of the disk, its rim included, and the normal points from that point
    to the centre.  With n the unit normal, p the centre of the grain relative to the
    centre of the disk, h = p . n and rho = |p - h n| its distance from the axis:

        rho <= R:  distance |h|,                        normal sign(h) n  (n when h = 0);
        rho > R:   distance sqrt(h^2 + (rho - R)^2),   normal (h n + (rho - R) e) / distance,

    e = (p - h n) / rho the outward radial direction: beyond the rim the grain touches
    the rim's nearest point, so a grain at the edge of the plate is pushed along the line
    from the rim to its centre.  Zero thickness, like the Segment: it holds grains only
    while their overlap stays below their radius.

    area [m^2] turns the wall force into a stress: pi R^2 when None.  The normal force
    (Walls.normal_force) is |F . n|, the magnitude of the grains' force along the normal
    (either side).
    """

    center: tuple
    normal: tuple
    radius: float
    material: int = 0
    motion: Motion = field(default_factory=Motion)
    name: str = "disk"
    area: float | None = None

    def __post_init__(self):
        if not (self.radius > 0 and math.isfinite(self.radius)):
            raise ValueError(f"disk {self.name!r}: radius must be finite and > 0 [m], got "
                             f"{self.radius}")
        if self.area is None:
            self.area = math.pi * float(self.radius) ** 2

    def row(self):
        center = np.asarray(self.center, dtype=np.float64)
        if center.shape != (3,) or not np.all(np.isfinite(center)):
            raise ValueError(f"disk {self.name!r}: center must be a finite 3-vector [m], got "
                             f"{center}")
        return DISK, np.array([*center, *_unit(self.normal, "disk normal"), float(self.radius)])


def box(lo, hi, material=0, open_top=True, dim=3):
    """The planes of an axis-aligned box [lo, hi] [m], inward normals, named by face.

    open_top leaves out the face at hi along the last axis (z in 3D, y in 2D).
    In 2D only the x and y faces exist; areas are then lengths [m] (per unit depth).
    """
    lo = np.asarray(lo, dtype=np.float64)
    hi = np.asarray(hi, dtype=np.float64)
    if lo.shape != (dim,) or hi.shape != (dim,) or np.any(hi <= lo):
        raise ValueError(f"box needs lo < hi with {dim} components, got {lo}, {hi}")
    size = hi - lo
    planes = []
    for a in range(dim):
        other = np.prod(np.delete(size, a)) if dim == 3 else float(np.delete(size, a)[0])
        for side, point in (("lo", lo), ("hi", hi)):
            if open_top and a == dim - 1 and side == "hi":
                continue
            n = np.zeros(3)
            n[a] = 1.0 if side == "lo" else -1.0
            p = np.zeros(3)
            p[:dim] = lo
            p[a] = point[a]
            planes.append(Plane(tuple(p), tuple(n), material, name=f"{'xyz'[a]}{side}",
                                area=float(other)))
    return planes


@dataclass(frozen=True)
class Periodic:
    """Periodic direction ``axis`` (0, 1, 2) over [lo, hi) [m]."""

    axis: int
    lo: float
    hi: float


class PeriodicBox(NamedTuple):
    """The periodic directions as every engine's compiled loops read them
    (Walls.periodic_box).

    flag : (3,) int64, 1 along a periodic axis
    lo : (3,) float64 [m] lower bound of the periodic cell along each axis
    length : (3,) float64 [m] its length (0 along a non-periodic axis)
    """
    flag: np.ndarray
    lo: np.ndarray
    length: np.ndarray


class Walls:
    """The walls of a simulation, as kernel arrays, plus periodic directions.  The
    layers above an engine read them; they move walls through the engine's set_motion,
    set_servo and place_wall (core/engine.py)."""

    def __init__(self, walls=(), periodic=()):
        self.walls = list(walls)
        w = len(self.walls)
        self.kind = np.zeros(w, np.int64)
        self.geometry = np.zeros((max(w, 1), GEOMETRY_WIDTH))[:w]
        self.motion_kind = np.zeros(w, np.int64)
        self.motion = np.zeros((w, MOTION_WIDTH))
        self.material = np.zeros(w, np.int32)
        for k, wall in enumerate(self.walls):
            self.kind[k], row = wall.row()
            self.geometry[k, :row.size] = row      # the unused columns stay 0
            self.motion_kind[k], self.motion[k] = wall.motion.row()
            self.material[k] = wall.material
        self.offset = np.zeros((w, 3))
        self.base = np.zeros((w, 3))
        self.velocity = np.zeros((w, 3))
        self.force = np.zeros((w, 3))
        self.periodic_flag = np.zeros(3, np.int64)
        self.periodic_lo = np.zeros(3)
        self.periodic_length = np.zeros(3)
        for p in periodic:
            if p.axis not in (0, 1, 2) or not p.hi > p.lo:
                raise ValueError(f"periodic direction needs axis in 0..2 and hi > lo, got {p}")
            self.periodic_flag[p.axis] = 1
            self.periodic_lo[p.axis] = p.lo
            self.periodic_length[p.axis] = p.hi - p.lo

    def __len__(self):
        return len(self.walls)

    def periodic_box(self):
        """The periodic directions (PeriodicBox of this object's arrays)."""
        return PeriodicBox(flag=self.periodic_flag, lo=self.periodic_lo,
                           length=self.periodic_length)

    def distances(self, points, ids):
        """Distance [m] from wall ids[k] to points[k] and the unit normal from the wall to
        the point, (K,) and (K, 3): the NumPy twin of ``wall_distance``."""
        g = self.geometry[ids]
        rel = points - g[:, :3] - self.offset[ids]
        axis = g[:, 3:6]
        along = np.einsum("ka,ka->k", rel, axis)
        perp = rel - along[:, None] * axis
        rho = np.linalg.norm(perp, axis=1)
        plane = self.kind[ids] == PLANE
        safe = np.where(rho > 0, rho, 1.0)[:, None]
        dist = np.where(plane, along, g[:, 6] - rho)
        normal = np.where(plane[:, None], axis, -perp / safe)
        segment = self.kind[ids] == SEGMENT
        if segment.any():
            dist[segment], normal[segment] = _segment_distances(
                rel[segment], axis[segment], g[segment, 7:10], along[segment],
                g[segment, 6] != 0)
        disk = self.kind[ids] == DISK
        if disk.any():
            dist[disk], normal[disk] = _disk_distances(along[disk], axis[disk], perp[disk],
                                                       rho[disk], g[disk, 6])
        return dist, normal

    def index(self, name):
        """Index of the wall called ``name`` (an index is returned as it is, once checked)."""
        if isinstance(name, (int, np.integer)):
            if not 0 <= name < len(self.walls):
                raise IndexError(f"no wall {name}: there are {len(self.walls)}")
            return int(name)
        for k, w in enumerate(self.walls):
            if w.name == name:
                return k
        raise KeyError(f"no wall named {name!r}; walls are {[w.name for w in self.walls]}")

    def prescribe(self, k, motion, now):
        """Wall k (index or name) follows ``motion`` from ``now`` [s] on (every engine's
        set_motion): from its start or now, whichever is later, from where the wall is
        (a sinusoid's reference place, ``base``, is set there); a fixed wall stops at
        once.  Returns the wall's index."""
        k = self.index(k)
        kind, row = motion.row()
        row[7] = max(row[7], now)
        self.motion_kind[k], self.motion[k] = kind, row
        self.base[k] = self.offset[k]
        if kind == FIXED:
            self.velocity[k] = 0.0
        return k

    def servo(self, k, *, force=None, stress=None, gain=None, time_constant=None,
              stiffness=None, max_speed=None, direction=None):
        """The servo Motion of wall k that every engine's set_servo asks for (the settings
        of core.engine.Engine.set_servo; those not given kept from a wall that is a servo
        already); ValueError naming what is missing or contradicts."""
        k = self.index(k)
        name = self.walls[k].name
        if stress is not None:
            if force is not None:
                raise ValueError("set_servo takes force= or stress=, not both")
            if self.walls[k].area is None:
                raise ValueError(f"wall {name!r} has no area: give the servo a force [N]")
            force = stress * self.walls[k].area
        if time_constant is not None or stiffness is not None:
            if gain is not None or time_constant is None or stiffness is None \
                    or not time_constant > 0 or not stiffness > 0:
                raise ValueError("set_servo takes gain= [m/(N s)], or time_constant= [s] "
                                 "and stiffness= [N/m], both > 0")
            gain = 1.0 / (stiffness * time_constant)
        settings = {"force": force, "gain": gain, "max_speed": max_speed,
                    "direction": direction}
        now = self.motion_of(k)
        for key, value in settings.items():
            if value is None:
                if now.kind != "servo":
                    raise ValueError(f"set_servo: wall {name!r} is not a servo yet: give "
                                     f"its {key}")
                settings[key] = getattr(now, key)
        return Motion("servo", **settings)

    def place(self, k, offset):
        """Put wall k (index or name) at ``offset`` (3,) [m] from where it was built, at
        once (every engine's place_wall; a sinusoid goes on about the new place).
        Returns the wall's index; ValueError unless a finite 3-vector."""
        k = self.index(k)
        offset = np.asarray(offset, dtype=np.float64)
        if offset.shape != (3,) or not np.all(np.isfinite(offset)):
            raise ValueError(f"wall offset must be a finite 3-vector [m], got {offset}")
        self.base[k] += offset - self.offset[k]
        self.offset[k] = offset
        return k

    def motion_of(self, k):
        """The Motion wall k (index or name) follows now (Motion.from_row)."""
        k = self.index(k)
        return Motion.from_row(self.motion_kind[k], self.motion[k])

    def minimum_image(self, vectors):
        """Separation vectors (K, 3) [m] wrapped to their shortest image along the
        periodic directions (the NumPy twin of neighbors.min_image)."""
        wrapped = np.array(vectors, dtype=np.float64)
        for d in np.flatnonzero(self.periodic_flag):
            length = self.periodic_length[d]
            wrapped[:, d] -= length * np.floor(wrapped[:, d] / length + 0.5)
        return wrapped

    def normal_force(self, k):
        """Force [N] the grains push on wall k along its inward normal (plane), its
        magnitude (cylinder: outward; segment: either side) or the magnitude of its
        component along the normal (disk: either side)."""
        if self.kind[k] == PLANE:
            return float(-self.force[k] @ self.geometry[k, 3:6])
        if self.kind[k] == DISK:
            return abs(float(self.force[k] @ self.geometry[k, 3:6]))
        return float(np.linalg.norm(self.force[k]))

    def stress(self, k):
        """Normal stress [Pa] on wall k: normal force over its area (None if no area)."""
        a = self.walls[k].area
        return None if a is None else self.normal_force(k) / a


def _segment_distances(rel, a, b, along, open_ends):
    """Distance [m] from segments (rectangles) of edges a, b (K, 3) to points at rel
    (K, 3) from their start, rel . a given, and the unit normals: wall_distance's segment
    branch (``open_ends`` (K,): inf and (1, 0, 0) for a point not over its wall)."""
    s = along / np.einsum("ka,ka->k", a, a)
    bb = np.einsum("ka,ka->k", b, b)
    t = np.where(bb > 0, np.einsum("ka,ka->k", rel, b) / np.where(bb > 0, bb, 1.0), 0.0)
    beyond = open_ends & ((s < 0) | (s > 1) | (t < 0) | (t > 1))
    s = np.clip(s, 0.0, 1.0)
    t = np.clip(t, 0.0, 1.0)
    r = rel - s[:, None] * a - t[:, None] * b
    rho = np.linalg.norm(r, axis=1)
    on = rho == 0
    if on.any():                     # on the wall: its face normal a x b (segment: a turned)
        ao, bo = a[on], b[on]
        face = np.where((bb[on] > 0)[:, None], np.cross(ao, bo),
                        np.stack([-ao[:, 1], ao[:, 0], np.zeros(len(ao))], axis=1))
        size = np.linalg.norm(face, axis=1)
        r[on] = np.where((size > 0)[:, None], face / np.where(size > 0, size, 1.0)[:, None],
                         [1.0, 0.0, 0.0])
    normal = r / np.where(on, 1.0, rho)[:, None]
    rho[beyond] = np.inf
    normal[beyond] = (1.0, 0.0, 0.0)
    return rho, normal


def _disk_distances(along, n, perp, rho, radius):
    """Distance [m] from disks of unit normals n (K, 3) and radii (K,) [m] to points at
    height ``along`` over their plane and ``perp`` (K, 3) from their axis (|perp| = rho),
    and the unit normals: wall_distance's disk branch (Disk)."""
    over = rho - radius
    outside = over > 0
    face = np.where((along < 0)[:, None], -n, n)
    safe = np.where(rho > 0, rho, 1.0)[:, None]
    r = along[:, None] * n + np.maximum(over, 0.0)[:, None] * perp / safe
    dist = np.where(outside, np.hypot(along, np.maximum(over, 0.0)), np.abs(along))
    normal = np.where(outside[:, None], r / np.where(outside, dist, 1.0)[:, None], face)
    return dist, normal


@scalar
def segment_distance(geometry, w, px, py, pz, ax, ay, az, along, open_ends):
    """wall_distance of segment (rectangle) w to a point at (px, py, pz) [m] from its
    start, along = p . a (a = (ax, ay, az), its first edge): the distance to its closest
    point, ends and edges included, or with ``open_ends`` inf for a point not over it
    (Segment.ends)."""
    s = along / (ax * ax + ay * ay + az * az)
    bx = geometry[w, 7]
    by = geometry[w, 8]
    bz = geometry[w, 9]
    bb = bx * bx + by * by + bz * bz
    t = 0.0
    if bb > 0.0:
        t = (px * bx + py * by + pz * bz) / bb
    if open_ends and (s < 0.0 or s > 1.0 or t < 0.0 or t > 1.0):
        return math.inf, 1.0, 0.0, 0.0      # open ends: not over the wall, no contact
    s = min(max(s, 0.0), 1.0)
    t = min(max(t, 0.0), 1.0)
    rx = px - s * ax - t * bx
    ry = py - s * ay - t * by
    rz = pz - s * az - t * bz
    rho = math.sqrt(rx * rx + ry * ry + rz * rz)
    if rho == 0.0:         # on the wall: its face normal a x b (segment: a turned)
        nx = ay * bz - az * by
        ny = az * bx - ax * bz
        nz = ax * by - ay * bx
        if bb == 0.0:
            nx = -ay
            ny = ax
            nz = 0.0
        size = math.sqrt(nx * nx + ny * ny + nz * nz)
        if size == 0.0:
            return 0.0, 1.0, 0.0, 0.0
        return 0.0, nx / size, ny / size, nz / size
    inverse = 1.0 / rho
    return rho, rx * inverse, ry * inverse, rz * inverse


@scalar
def wall_distance(kind, geometry, offset, w, x, y, z):
    """Distance [m] from the surface of wall w to a point, and the unit normal pointing
    from the wall to the point (plane: signed distance on the normal side; cylinder:
    radius minus the distance to the axis; segment: distance to its closest point,
    edges and ends included, >= 0 on either side, or inf for a point not over a segment
    of open ends; disk: distance to its closest point, rim included, >= 0 on either
    side, Disk)."""
    return _distance(kind, geometry, offset, w, x, y, z, True)


@scalar
def wall_reach(kind, geometry, offset, w, x, y, z):
    """A lower bound [m] on wall_distance that changes continuously with the point: the
    distance itself, except that an open-ended segment counts with round ends, so that
    the neighbour lists (neighbors.wall_row) keep as a candidate a grain that may come
    over it before they are rebuilt."""
    return _distance(kind, geometry, offset, w, x, y, z, False)[0]


@scalar
def _distance(kind, geometry, offset, w, x, y, z, open_ends):
    """wall_distance, with the open ends of segments honoured or not (``open_ends``)."""
    px = x - geometry[w, 0] - offset[w, 0]
    py = y - geometry[w, 1] - offset[w, 1]
    pz = z - geometry[w, 2] - offset[w, 2]
    ax = geometry[w, 3]
    ay = geometry[w, 4]
    az = geometry[w, 5]
    along = px * ax + py * ay + pz * az
    if kind[w] == PLANE:
        return along, ax, ay, az
    if kind[w] == SEGMENT:     # (ax, ay, az) is the edge a
        return segment_distance(geometry, w, px, py, pz, ax, ay, az, along,
                                open_ends and geometry[w, 6] != 0.0)
    rx = px - along * ax
    ry = py - along * ay
    rz = pz - along * az
    rho = math.sqrt(rx * rx + ry * ry + rz * rz)
    if kind[w] == DISK:        # (ax, ay, az) is the unit normal; (rx, ry, rz) off the axis
        over = rho - geometry[w, 6]
        if over <= 0.0:        # over the face
            if along < 0.0:
                return -along, -ax, -ay, -az
            return along, ax, ay, az
        scale = over / rho     # from the rim's nearest point to the point: along n + over e
        dx = along * ax + scale * rx
        dy = along * ay + scale * ry
        dz = along * az + scale * rz
        dist = math.sqrt(along * along + over * over)
        inverse = 1.0 / dist
        return dist, dx * inverse, dy * inverse, dz * inverse
    if rho == 0.0:
        return geometry[w, 6], 1.0, 0.0, 0.0
    inverse = 1.0 / rho      # one division, not three (the CPU's wall walk: scalar)
    return geometry[w, 6] - rho, -rx * inverse, -ry * inverse, -rz * inverse


@kernel
def walls_advance(motion_kind, motion, base, offset, velocity, force, time, dt):
    """Move prescribed, servo and piston walls from ``time`` to ``time + dt`` [s]; ``force``
    (W, 3) [N] is the force of the grains on each wall at the last evaluation."""
    t = time + dt
    for w in range(motion_kind.size):
        kind = motion_kind[w]
        if kind == VELOCITY and t > motion[w, 7]:
            for d in range(3):
                velocity[w, d] = motion[w, d] * motion[w, 3]
                offset[w, d] += velocity[w, d] * dt
        elif kind == SINUSOID and t > motion[w, 7]:
            omega = 2.0 * math.pi * motion[w, 5]
            arg = omega * (t - motion[w, 7]) + motion[w, 6]
            for d in range(3):
                offset[w, d] = base[w, d] + motion[w, d] * motion[w, 4] * (
                    math.sin(arg) - math.sin(motion[w, 6]))
                velocity[w, d] = motion[w, d] * motion[w, 4] * omega * math.cos(arg)
        elif kind == SERVO and t > motion[w, 7]:
            push = -(force[w, 0] * motion[w, 0] + force[w, 1] * motion[w, 1]
                     + force[w, 2] * motion[w, 2])
            speed = min(max(motion[w, 4] * (motion[w, 3] - push), -motion[w, 5]), motion[w, 5])
            for d in range(3):
                velocity[w, d] = motion[w, d] * speed
                offset[w, d] += velocity[w, d] * dt
        elif kind == PISTON and t > motion[w, 7]:
            applied = motion[w, 3] + motion[w, 4] * math.sin(
                2.0 * math.pi * motion[w, 5] * (time - motion[w, 7]) + motion[w, 6])
            push = 0.0
            speed = 0.0
            for d in range(3):
                push -= force[w, d] * motion[w, d]
                speed += velocity[w, d] * motion[w, d]
            speed += dt * (applied - push) / motion[w, 8]
            for d in range(3):
                velocity[w, d] = motion[w, d] * speed
                offset[w, d] += velocity[w, d] * dt
        else:
            for d in range(3):
                velocity[w, d] = 0.0
