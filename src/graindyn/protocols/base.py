"""What a protocol is made of: a container (``Vessel``), phases that each run an engine
from where it stands (``Phase``) and the sequence of them (``Protocol``); and
``PROTOCOLS``, the one registry of protocols, read by config validation (the
``[protocol]`` section is the settings class of its ``kind``), the runner, sweeps and
``graindyn info``.

A protocol never sees the Config: it is made from its own settings (a Section) and
the Vessel, and its phases receive the engine (core.engine.Engine) and use only its
interface.  Each phase keeps its progress in a JSON-able dict that checkpoints carry,
deadlines as simulated time, so a resumed run picks up inside the phase where it
stopped and ends it where the uninterrupted run would have.
"""
import math
from dataclasses import dataclass, replace

import numpy as np

from ..schema import Section
from .prepare import BoxRegion, CylinderRegion


@dataclass(frozen=True)
class Vessel:
    """The container the grains fill, as protocols need it.

    dim : 2 or 3.  shape : "box" or "cylinder".
    lo, hi : (dim,) [m] the box's corners; for a cylinder the bounding box of its
      inside, from the bottom (z = 0) to its height.
    center, radius : the cylinder's axis (x, y) [m] and radius [m] (None for a box).
    open_top : no wall at the top (a box built with open_top; a cylinder unless a
      protocol closes it with a lid or piston at its top, ``closed``).
    bottom_wall, side_walls : the names of its walls.
    cross_section [m^2] (2D: width [m]) and perimeter [m] (2D: 2, the two sides).
    symmetry : the symmetry planes (core.symmetry.Symmetry) that cut it (``mirrored``):
      lo, hi, cross_section and perimeter are then those of the part the grains fill.
    """

    dim: int
    shape: str
    lo: tuple
    hi: tuple
    open_top: bool
    bottom_wall: str
    side_walls: tuple
    cross_section: float
    perimeter: float
    center: tuple | None = None
    radius: float | None = None
    symmetry: tuple = ()

    @classmethod
    def box(cls, lo, hi, open_top, dim):
        lo, hi = tuple(float(x) for x in lo), tuple(float(x) for x in hi)
        span = np.subtract(hi, lo)
        sides = ("xlo", "xhi", "ylo", "yhi")[:2 * (dim - 1)]
        return cls(dim, "box", lo, hi, open_top, "zlo" if dim == 3 else "ylo", sides,
                   float(np.prod(span[:-1])),
                   2.0 * float(np.sum(span[:2])) if dim == 3 else 2.0)

    @classmethod
    def cylinder(cls, center, radius, height):
        cx, cy = (float(x) for x in center)
        return cls(3, "cylinder", (cx - radius, cy - radius, 0.0),
                   (cx + radius, cy + radius, float(height)), True, "bottom", ("side",),
                   math.pi * radius**2, 2.0 * math.pi * radius, (cx, cy), float(radius))

    def mirrored(self, planes):
        """The part of this vessel on the grains' side of the symmetry planes ``planes``
        (core.symmetry.Symmetry), each a symmetry plane of the vessel: normal to a
        horizontal axis, through the middle of a box or the axis of a cylinder.  Each
        halves the cross-section and the perimeter of the side walls.  ValueError for
        another plane."""
        if not planes:
            return self
        lo, hi = list(self.lo), list(self.hi)
        for p in planes:
            d = p.index
            middle = 0.5 * (self.lo[d] + self.hi[d]) if d < self.dim else None
            if d >= self.dim - 1 or not math.isclose(p.at, middle, rel_tol=0,
                                                      abs_tol=1e-12 * (self.hi[d] - self.lo[d])):
                raise ValueError(
                    f"symmetry plane {'xyz'[d]} = {p.at:.6g} m: a symmetry plane of the "
                    f"{self.shape} is normal to a horizontal axis ("
                    f"{' or '.join('xyz'[:self.dim - 1])}) and passes through its "
                    f"{'axis' if self.shape == 'cylinder' else 'middle'}"
                    + (f" ({'xyz'[d]} = {middle:.6g} m)" if middle is not None else ""))
            if p.side > 0:
                lo[d] = p.at
            else:
                hi[d] = p.at
        share = 0.5 ** len(planes)
        return type(self)(self.dim, self.shape, tuple(lo), tuple(hi), self.open_top,
                          self.bottom_wall, self.side_walls, share * self.cross_section,
                          share * self.perimeter, self.center, self.radius, tuple(planes))

    def closed(self):
        """This vessel with a wall at its top (a lid, a piston): nothing is inserted
        above it."""
        return replace(self, open_top=False)

    @property
    def floor(self):
        """Height [m] of the bottom (z in 3D, y in 2D)."""
        return self.lo[-1]

    @property
    def top(self):
        """Height [m] of the top of the container (its ceiling when closed)."""
        return self.hi[-1]

    def region(self, height):
        """The insertion region from the floor up to ``height`` [m] above it; ValueError
        when a closed vessel is lower than that."""
        top = self.floor + height
        if not self.open_top and top > self.top:
            raise ValueError(f"the grains need an insertion region {height:.4g} m high but "
                             f"the closed {self.shape} is only {self.top - self.floor:.4g} m "
                             "high: make it taller, raise the packing fraction of the "
                             "insertion or lower the count")
        if self.shape == "box":
            return BoxRegion(self.lo[:-1] + (self.floor,), self.hi[:-1] + (top,))
        return CylinderRegion(self.center, self.radius, self.floor, top,
                              self.lo[:2] if self.symmetry else None,
                              self.hi[:2] if self.symmetry else None)


class Phase:
    """One stage of a protocol.  ``name`` keys its progress in the run's state;
    ``duration`` is its longest simulated time [s] (for the progress bar)."""

    name = "phase"

    def duration(self):
        """Longest simulated time [s] of the phase."""
        return math.inf

    def run(self, engine, state, *, every=(), between=None):
        """Run the phase on ``engine`` from where it stands; ``state`` (dict, JSON-able)
        records how far it got.  every and between as Engine.run.  Returns "done", or
        "stopped" when ``between`` stopped it (call again with the same state)."""
        raise NotImplementedError

    def report(self, engine, state):
        """What the phase has to say of the engine when it ends (dict), kept in its
        state as state["report"]."""
        return {}

    def verdict(self, state):
        """A line for the run log when the phase has ended, from its ``state``: what a
        user should know of how it ended (None: nothing)."""
        return None


class ProtocolPhase(Phase):
    """A phase of a protocol's own: it reads the protocol (its log, folder and title),
    its settings ``p`` and its ``vessel``."""

    def __init__(self, protocol):
        self.protocol = protocol
        self.p = protocol.p
        self.vessel = protocol.vessel


def write_rows(path, rows, keys=None):
    """Write ``rows`` (dicts) as CSV to ``path``, the columns ``keys`` (default: those of
    the first row); returns the path."""
    keys = list(rows[0]) if keys is None and rows else list(keys or [])
    path.write_text("\n".join([",".join(keys)] + [",".join(str(r[k]) for k in keys)
                                                  for r in rows]) + "\n")
    return path


def lower_onto_grains(engine, wall):
    """Put ``wall``, a plane facing down the vertical axis (z in 3D, y in 2D), at
    1e-3 of the smallest radius above the highest grain (a piston or plate put on the
    sample)."""
    s = engine.state
    up = s.dim - 1
    k = engine.walls.index(wall)
    offset = engine.walls.offset[k].copy()
    offset[up] = float(np.max(s.positions[:, up] + s.radii)) \
        + 1e-3 * float(s.radii.min()) - engine.walls.geometry[k, up]
    engine.place_wall(k, offset)


def run_until(engine, state, key, duration, **run):
    """Run ``engine`` until the deadline ``state[key]`` [s] of simulated time, set to
    now + ``duration`` the first time (so a resumed phase keeps its deadline)."""
    end = state.setdefault(key, engine.time + duration)
    return engine.run(time=max(0.0, end - engine.time), **run)


class Protocol:
    """A sequence of phases run on one engine.

    Subclasses set ``kind`` (the config's protocol.kind), ``settings`` (the Section class
    of the ``[protocol]`` section: its ``kind`` field a Literal of ``kind``), ``summary``
    (a line for graindyn info) and build ``phases`` in __init__.  They may add walls
    (``walls``), turn the phases' reports into results, tables and figures, and offer
    ``summarize_sweep(sweep_dir, points)`` for sweeps of their runs.
    """

    kind = "protocol"
    settings = Section
    summary = ""
    summarize_sweep = None
    title = "run"      # the run's name, in figure titles (the runner sets it)
    folder = None      # the run directory, for files of the protocol's own (the runner sets it)
    seed = 0           # the run's seed, for draws of the protocol's own (config.build sets it)

    def __init__(self, settings, vessel: Vessel):
        self.p = settings
        self.vessel = vessel
        self.phases = ()

    @staticmethod
    def log(message):
        """Where the protocol reports its progress (the runner sets the run log)."""

    @classmethod
    def cross_check(cls, config):
        """ValueError when the protocol cannot run the rest of ``config`` (dimension,
        container); called by config validation, which has checked that the config has
        a container."""

    @classmethod
    def wall_motions(cls, settings):
        """The wall motions (core.walls.Motion kinds) the protocol gives walls with
        ``settings``, beyond "fixed": config validation checks that the engine offers
        them (engines.EngineKind.wall_motions)."""
        return set()

    @classmethod
    def materials_named(cls, settings):
        """(where, material name) pairs of the materials ``settings`` name (config
        validation checks that each exists)."""
        return []

    def walls(self, container, material_index):
        """The walls (core.walls) of the run from ``container``, the walls of the
        config's container and its extra walls: as they are (the default), with walls
        of the protocol's own added (the oedometer's piston) or some replaced (the
        silo's floor with its hole).  material_index(name) gives a material's id (None:
        the walls' material)."""
        return list(container)

    def series_columns(self, engine):
        """Columns of the protocol's own for every row of the run's time series
        (series.csv, after output.writers.series_row's): {name with its unit: value},
        the same names at every row."""
        return {}

    def results(self, engine, states):
        """The run's results from the phases' states (dict of name -> state)."""
        return {name: state.get("report", {}) for name, state in states.items()}

    def tables(self, rundir, results):
        """Tables written beside results.json; their paths."""
        return []

    def figures(self, rundir, series, results):
        """Figures of the run from its series (output.rundir.Series.read()); their paths."""
        return []


PROTOCOLS: dict[str, type[Protocol]] = {}


def register(protocol):
    """Add a Protocol class to PROTOCOLS under its kind (new kinds only); returns it, so
    it serves as a class decorator."""
    if protocol.kind in PROTOCOLS and PROTOCOLS[protocol.kind] is not protocol:
        raise ValueError(f"protocol kind {protocol.kind!r} is registered already")
    PROTOCOLS[protocol.kind] = protocol
    return protocol


def settings_classes():
    """kind -> settings Section class, for config validation."""
    return {kind: protocol.settings for kind, protocol in PROTOCOLS.items()}
