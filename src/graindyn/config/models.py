"""The run configuration: one pydantic model per TOML section (SI units throughout).

Every field states its unit and allowed range in its description and enforces the range
with bounds; unknown keys are rejected; every number is a finite ``Float`` or ``Int``
(never a boolean or a string); cross-field rules are checked in the
``model_validator``s.  A script builds the same ``Config`` from a dict, so a script and
a TOML file describe the same run.
"""
import warnings
from typing import Literal

from pydantic import SerializeAsAny, field_validator, model_validator

from .. import engines, protocols
from ..core.symmetry import SymmetryPlanes
from ..physics import registry
from ..schema import Float, Int, Section, by_kind, described

_f = described


class RunSection(Section):
    name: str = _f("run", "name of the run (used in file names and figure titles)")
    seed: Int = _f(1, "random seed [-] of everything random (insertion, velocities); >= 0",
                   ge=0)
    dim: Literal[2, 3] = _f(3, "dimension: 3 (spheres) or 2 (disks in the x-y plane)")
    backend: Literal["cpu", "gpu"] = _f("cpu", "compute backend: cpu or gpu")
    threads: Int = _f(0, "CPU threads [-], 0 = automatic (one thread for a small system, "
                      "every core for a large one: graindyn info); 0..1024", ge=0, le=1024)
    gravity: tuple[Float, Float, Float] = _f(
        (0.0, 0.0, -9.81), "gravity [m/s^2]; in 2D the z component must be 0")


class DiameterSection(Section):
    distribution: Literal["uniform", "normal", "lognormal"] = _f(
        "uniform", "diameter distribution: uniform in [min, max] (Oquendo, Perez), normal "
        "or lognormal (mean, std of the diameter)")
    min: Float | None = _f(None, "smallest diameter [m] (uniform); (0, 1]", gt=0, le=1)
    max: Float | None = _f(None, "largest diameter [m] (uniform); (0, 1]", gt=0, le=1)
    mean: Float | None = _f(None, "mean diameter [m] (normal, lognormal); (0, 1]", gt=0,
                            le=1)
    std: Float | None = _f(None, "standard deviation of the diameter [m]; [0, 1]", ge=0,
                           le=1)

    @model_validator(mode="after")
    def _consistent(self):
        if self.distribution == "uniform":
            if self.min is None or self.max is None:
                raise ValueError("a uniform distribution needs min and max [m]")
            if self.min > self.max:
                raise ValueError(f"min = {self.min} must be <= max = {self.max} [m]")
        elif self.mean is None or self.std is None:
            raise ValueError(f"a {self.distribution} distribution needs mean and std [m]")
        return self

    def as_kwargs(self):
        """Keyword arguments of state.sample_radii."""
        if self.distribution == "uniform":
            return {"d_min": self.min, "d_max": self.max}
        return {"mean": self.mean, "std": self.std}

    def smallest(self):
        """A lower bound of the diameters drawn [m] (for the time-step check)."""
        if self.distribution == "uniform":
            return self.min
        return max(self.mean - 4 * self.std, 0.05 * self.mean)


class GrainsSection(Section):
    count: Int = _f(..., "number of grains [-]; 1..1e8", ge=1, le=100_000_000)
    diameter: DiameterSection = _f(..., "grain diameters")
    material: str = _f(..., "name of the grain material (one of [[materials]])")


class MaterialSection(Section):
    """Mirrors core.species.Material field by field (a test keeps the two in step)."""

    name: str = _f(..., "material name, referenced by grains and walls")
    density: Float = _f(2650.0, "density [kg/m^3] (2D: areal [kg/m^2]); (0, 1e5]", gt=0,
                        le=1e5)
    youngs_modulus: Float = _f(1e8, "Young's modulus E [Pa]; (0, 1e13]", gt=0, le=1e13)
    poisson_ratio: Float = _f(0.3, "Poisson ratio nu [-]; (-1, 0.5)", gt=-1, lt=0.5)
    restitution: Float | None = _f(None, "normal restitution coefficient [-] setting the "
                                   "damping of the chosen law; (0, 1]", gt=0, le=1)
    damping_constant: Float = _f(0.0, "linear dashpot constant Gamma [kg/s]; >= 0", ge=0)
    gamma_n: Float = _f(0.0, "viscoelastic Hertz damping gamma_n [1/(s m^0.5)] (Oquendo "
                        "Eq. 1); >= 0", ge=0)
    kn: Float = _f(0.0, "linear normal stiffness [N/m]; >= 0", ge=0)
    kt: Float = _f(0.0, "linear tangential stiffness [N/m]; >= 0", ge=0)
    friction_sliding: Float = _f(0.5, "sliding friction coefficient mu_k [-]; [0, 10]",
                                 ge=0, le=10)
    friction_static: Float = _f(0.5, "static friction coefficient mu_s [-]; [0, 10]",
                                ge=0, le=10)
    friction_rolling: Float = _f(0.0, "rolling friction coefficient [-]; [0, 10]", ge=0,
                                 le=10)
    tangential_damping: Float = _f(0.0, "tangential/normal dashpot ratio [-]; [0, 1e6]",
                                   ge=0, le=1e6)
    slip_threshold: Float = _f(1e-5, "Oquendo's contact-point speed below which grains "
                               "stick or roll [m/s] (Eq. 4, 7); >= 0", ge=0)
    gamma_nt: Float = _f(0.0, "Oquendo's twisting damping gamma_nt [1/s] (Eq. 2); >= 0",
                         ge=0)
    alpha_n: Float = _f(0.0, "Karrech's normal dissipation coefficient alpha [-] (Eq. 7); "
                        ">= 0", ge=0)
    alpha_t: Float = _f(0.0, "Karrech's tangential dissipation coefficient alpha [-] "
                        "(Eq. 7); >= 0", ge=0)
    rolling_stiffness: Float = _f(0.0, "EPSD rolling spring [N/m] (torque through R*^2); "
                                  ">= 0", ge=0)
    rolling_damping: Float = _f(0.0, "EPSD rolling dashpot [kg/s]; >= 0", ge=0)
    friction_twisting: Float = _f(0.0, "twisting friction coefficient [-] (limit "
                                  "mu_tw a |f_n|); [0, 10]", ge=0, le=10)
    twisting_stiffness: Float = _f(0.0, "EPSD twisting spring [N m/rad]; >= 0", ge=0)
    twisting_damping: Float = _f(0.0, "EPSD twisting dashpot [N m s]; >= 0", ge=0)


# pair-table columns that core.species computes from material fields of other names;
# every other column is mixed from the material field of its own name
_DERIVED = {"youngs_eff": ("youngs_modulus", "poisson_ratio"),
            "shear_eff": ("youngs_modulus", "poisson_ratio"),
            "damping_ratio": ("restitution",), "tsuji_alpha": ("restitution",)}


def material_fields(columns):
    """The material fields that the pair-table ``columns`` are computed from."""
    return {f for c in columns for f in _DERIVED.get(c, (c,))}


class PairOverride(Section):
    materials: tuple[str, str] = _f(..., "the two material names of the pair")
    values: dict[str, Float] = _f(..., "pair-table columns and their values (SI)")

    @field_validator("values")
    @classmethod
    def _columns(cls, values):
        unknown = sorted(set(values) - set(registry.COL))
        if unknown:
            raise ValueError(f"unknown pair columns {unknown}; columns are "
                             f"{sorted(registry.COL)}")
        return values


class ContactSection(Section):
    normal: str = _f("hertz", "normal elastic law (registry name)")
    damping: str = _f("tsuji", "normal damping law (registry name)")
    tangential: str = _f("mindlin", "tangential law (registry name)")
    rolling: str = _f("none", "rolling resistance law (registry name)")
    twisting: str = _f("none", "twisting resistance law (registry name)")
    limit_damping: bool = _f(True, "keep the normal force repulsive (Perez Eq. 14, 17)")
    overrides: list[PairOverride] = _f([], "per-pair column overrides")

    @model_validator(mode="after")
    def _laws_exist(self):
        for mode in registry.MODES:
            registry.law_id(mode, getattr(self, mode))  # ValueError names the choices
        return self


class MotionSection(Section):
    kind: Literal["fixed", "velocity", "sinusoid"] = _f("fixed", "prescribed wall motion")
    velocity: tuple[Float, Float, Float] = _f((0.0, 0.0, 0.0), "velocity [m/s] (velocity)")
    direction: tuple[Float, Float, Float] = _f((0.0, 0.0, 1.0),
                                               "direction of a sinusoid [-]")
    amplitude: Float = _f(0.0, "sinusoid amplitude [m]; >= 0", ge=0)
    frequency: Float = _f(1.0, "sinusoid frequency [Hz]; > 0", gt=0)
    phase: Float = _f(0.0, "sinusoid phase [rad]")
    start: Float = _f(0.0, "time the motion starts [s]; >= 0", ge=0)


class PlaneSection(Section):
    name: str = _f(..., "wall name (used in the outputs)")
    point: tuple[Float, Float, Float] = _f(..., "a point of the plane [m]")
    normal: tuple[Float, Float, Float] = _f(..., "normal pointing into the grains [-]")
    material: str | None = _f(None, "wall material; default: walls.material")
    area: Float | None = _f(None, "area [m^2] (2D: length [m]) for the stress; > 0", gt=0)
    motion: MotionSection = _f(MotionSection(), "prescribed motion")


class BoxContainer(Section):
    kind: Literal["box"] = "box"
    lo: list[Float] = _f(..., "lower corner [m] (dim components)")
    hi: list[Float] = _f(..., "upper corner [m] (dim components)")
    open_top: bool = _f(True, "leave out the face at hi along the last axis")


class CylinderContainer(Section):
    kind: Literal["cylinder"] = "cylinder"
    radius: Float = _f(..., "inner radius [m]; (0, 100]", gt=0, le=100)
    height: Float = _f(..., "height [m] of the cylinder above its bottom; (0, 1000]", gt=0,
                       le=1000)
    center: tuple[Float, Float] = _f((0.0, 0.0), "axis position (x, y) [m]; the axis is z")


class SymmetrySection(Section):
    """A symmetry plane (core.symmetry.Symmetry): the grains near it touch the mirror
    images of the grains near it, so the part of the system on one side behaves as the
    whole symmetric system (a quarter of a cylinder with two planes)."""

    axis: Literal["x", "y", "z"] = _f(..., "the axis normal to the plane")
    at: Float | None = _f(None, "coordinate of the plane along its axis [m]; default: the "
                          "container's centre (its axis for a cylinder)")
    side: Int = _f(1, "the side of the plane the grains are on: 1 above ``at``, -1 "
                   "below", ge=-1, le=1)


class SegmentSection(Section):
    """A finite wall (core.walls.Segment): in 2D the line segment from start to end in
    the x-y plane, in 3D the rectangle with corners start, end, end + edge, start + edge;
    two-sided, its edges and ends round unless ``ends = "open"``."""

    name: str = _f(..., "wall name (used in the outputs)")
    start: list[Float] = _f(..., "first end point [m] (3D: a corner of the rectangle); "
                            "2 or 3 components, z = 0 in 2D", min_length=2, max_length=3)
    end: list[Float] = _f(..., "second end point [m] (3D: the corner next to start); "
                          "2 or 3 components, z = 0 in 2D", min_length=2, max_length=3)
    edge: tuple[Float, Float, Float] | None = _f(
        None, "3D only: the rectangle's second edge [m], from start, perpendicular to "
        "end - start (required in 3D)")
    ends: Literal["round", "open"] = _f(
        "round", "round: grains touch its ends and edges too; open: it acts only on "
        "grains whose centre is over it (core.walls.Segment)")
    material: str | None = _f(None, "wall material; default: walls.material")
    area: Float | None = _f(None, "area [m^2] (2D: length [m]) for the stress; default "
                            "the segment's own; > 0", gt=0)
    motion: MotionSection = _f(MotionSection(), "prescribed motion")

    @model_validator(mode="after")
    def _not_degenerate(self):
        start, end = (list(p) + [0.0] * (3 - len(p)) for p in (self.start, self.end))
        a = [e - s for s, e in zip(start, end)]
        la = sum(x * x for x in a) ** 0.5
        if la == 0:
            raise ValueError(f"segment {self.name!r}: start and end coincide ({self.start})")
        if self.edge is not None:
            lb = sum(x * x for x in self.edge) ** 0.5
            if lb == 0:
                raise ValueError(f"segment {self.name!r}: edge must be non-zero")
            if abs(sum(x * y for x, y in zip(a, self.edge))) > 1e-9 * la * lb:
                raise ValueError(f"segment {self.name!r}: edge {self.edge} must be "
                                 f"perpendicular to end - start {a} (a rectangle)")
        return self

    def check_dim(self, dim, where):
        """ValueError unless the segment fits a ``dim``-D run (``where``: its path)."""
        if dim == 2 and (self.edge is not None or any(
                len(p) == 3 and p[2] != 0 for p in (self.start, self.end))):
            raise ValueError(f"{where}: a 2D segment lies in the x-y plane: z = 0 and no "
                             "edge")
        if dim == 3 and (self.edge is None or len(self.start) != 3 or len(self.end) != 3):
            raise ValueError(f"{where}: a 3D segment is a rectangle: give start and end "
                             "with 3 components and its edge")


class WallsSection(Section):
    material: str = _f(..., "default wall material (one of [[materials]])")
    container: BoxContainer | CylinderContainer | None = _f(
        None, "the container: a box or a vertical cylinder with a bottom at z = 0",
        discriminator="kind")
    planes: list[PlaneSection] = _f([], "additional planes")
    segments: list[SegmentSection] = _f(
        [], "finite walls: line segments (2D) or rectangles (3D), two-sided")
    periodic: list[tuple[Int, Float, Float]] = _f(
        [], "periodic directions as (axis 0..2, lo [m], hi [m])")
    symmetry: list[SymmetrySection] = _f(
        [], "symmetry planes, at most one per axis (soft engine, CPU): e.g. "
        "[{axis = \"x\"}, {axis = \"y\"}] for the quarter of a cylinder")


# where the fields of a section that older configs had now live
MOVED = {"integrator": ("engine", {"name": "integrator"})}


def moved(path):
    """The present dotted path of a field that ``path`` names in an older config (the
    [integrator] section is [engine] now, its ``name`` is ``integrator``), or None if
    ``path`` did not move."""
    section, _, field = path.partition(".")
    if section not in MOVED:
        return None
    target, renamed = MOVED[section]
    return f"{target}.{renamed.get(field, field)}" if field else target


class OutputSection(Section):
    series_every: Float = _f(1e-3, "time-series interval [s] of simulated time; > 0", gt=0)
    vtk_every: Float | None = _f(None, "VTK snapshot interval [s] of simulated time "
                                 "(None: first and last state only); > 0", gt=0)
    vtk_contacts: bool = _f(False, "also write the contact network (lines, normal force)")
    checkpoint_every_steps: Int | None = _f(200_000, "checkpoint interval [steps]; >= 1",
                                            ge=1)
    checkpoint_every_seconds: Float | None = _f(
        600.0, "checkpoint interval [s] of wall-clock time; > 0", gt=0)
    figures: bool = _f(True, "draw the figures (PNG), and pictures of the grains and "
                       "their force network at the start and the end")
    pictures_every: Float | None = _f(None, "interval [s] of simulated time between "
                                      "pictures of the force network (None: the start and "
                                      "the end only); > 0", gt=0)


class Config(Section):
    """A whole run."""

    run: RunSection = _f(RunSection(), "run identity, dimension, backend, gravity")
    grains: GrainsSection
    materials: list[MaterialSection] = _f(..., "materials of grains and walls",
                                          min_length=1)
    contact: ContactSection = _f(ContactSection(), "contact law, one per mode")
    walls: WallsSection
    engine: SerializeAsAny[Section] = _f(
        engines.ENGINES["soft"].settings(), "the engine that advances the grains and its "
        "own settings; kind: one of engines.ENGINES (graindyn info), default soft")
    protocol: SerializeAsAny[Section] = _f(
        protocols.PROTOCOLS["deposition"].settings(), "what the run does; kind: one of "
        "protocols.PROTOCOLS (graindyn info), default deposition")
    output: OutputSection = _f(OutputSection(), "what the run writes")

    _engine = field_validator("engine", mode="wrap")(
        classmethod(by_kind(engines.settings_classes, "engine", "soft")))
    _protocol = field_validator("protocol", mode="wrap")(
        classmethod(by_kind(protocols.base.settings_classes, "protocol", "deposition")))

    @model_validator(mode="before")
    @classmethod
    def _moved_sections(cls, data):
        """An older config still loads: its [integrator] section is read as [engine]
        (``name`` as ``integrator``), with a warning saying what to write instead; both
        sections at once are refused."""
        if not isinstance(data, dict):
            return data
        for section, (target, renamed) in MOVED.items():
            if section not in data:
                continue
            if target in data:
                raise ValueError(f"[{section}] and [{target}] both given: [{section}] is "
                                 f"the older name of [{target}]; move its fields there")
            fields = dict(data[section]) if isinstance(data[section], dict) else {}
            moved_fields = {renamed.get(k, k): v for k, v in fields.items()}
            warnings.warn(f"[{section}] is now [{target}]: write [{target}] with "
                          + ", ".join(f"{renamed.get(k, k)} = {v!r}"
                                      for k, v in fields.items())
                          + (" (" + ", ".join(f"{k} is now {v}" for k, v in renamed.items())
                             + ")" if renamed else ""), DeprecationWarning, stacklevel=2)
            data = {**{k: v for k, v in data.items() if k != section},
                    target: moved_fields}
        return data

    @model_validator(mode="after")
    def _cross_checks(self):
        names = [m.name for m in self.materials]
        if len(set(names)) != len(names):
            raise ValueError(f"materials: names must be unique, got {names}")
        used = [("grains.material", self.grains.material),
                ("walls.material", self.walls.material)]
        used += [(f"walls.planes.{k}.material", p.material)
                 for k, p in enumerate(self.walls.planes) if p.material is not None]
        used += [(f"walls.segments.{k}.material", s.material)
                 for k, s in enumerate(self.walls.segments) if s.material is not None]
        for k, s in enumerate(self.walls.segments):
            s.check_dim(self.run.dim, f"walls.segments.{k}")
        protocol = protocols.PROTOCOLS[self.protocol.kind]
        used += protocol.materials_named(self.protocol)
        used += [(f"contact.overrides.{k}.materials", m)
                 for k, o in enumerate(self.contact.overrides) for m in o.materials]
        for where, name in used:
            if name not in names:
                raise ValueError(f"{where} = {name!r} is not a material; materials are "
                                 f"{names}")
        dim = self.run.dim
        if dim == 2 and self.run.gravity[2] != 0:
            raise ValueError(f"run.gravity = {self.run.gravity}: the z component must be 0 "
                             "in 2D")
        box = self.walls.container
        if isinstance(box, BoxContainer):
            if len(box.lo) != dim or len(box.hi) != dim or any(
                    h <= lo for lo, h in zip(box.lo, box.hi)):
                raise ValueError(f"walls.container: a {dim}D box needs lo < hi with {dim} "
                                 f"components, got lo = {box.lo}, hi = {box.hi}")
        if isinstance(box, CylinderContainer) and dim == 2:
            raise ValueError("walls.container: a cylinder needs run.dim = 3")
        if box is None:
            raise ValueError(f"walls.container: the {self.protocol.kind} protocol needs a "
                             "container (box or cylinder)")
        protocol.cross_check(self)
        self._check_wall_motions(protocol)
        for axis, lo, hi in self.walls.periodic:
            if axis not in range(dim) or not hi > lo:
                raise ValueError(f"walls.periodic: ({axis}, {lo}, {hi}) needs axis in "
                                 f"0..{dim - 1} and hi > lo [m]")
        if self.walls.symmetry and not engines.ENGINES[self.engine.kind].symmetry:
            able = [e.kind for e in engines.ENGINES.values() if e.symmetry]
            raise ValueError(f"walls.symmetry: engine.kind = {self.engine.kind!r} has no "
                             f"symmetry planes; engines that do: {', '.join(able)}")
        if self.walls.symmetry and self.run.backend != "cpu":
            raise ValueError("walls.symmetry: symmetry planes run on the CPU backend only")
        if getattr(self.protocol, "settle_friction", None) is not None:
            if not engines.ENGINES[self.engine.kind].friction_change:
                able = [e.kind for e in engines.ENGINES.values() if e.friction_change]
                raise ValueError(f"protocol.settle_friction: engine.kind = "
                                 f"{self.engine.kind!r} cannot change its friction during a "
                                 f"run; engines that can: {', '.join(able)}")
            if self.run.backend != "cpu":
                raise ValueError("protocol.settle_friction runs on the CPU backend only")
        if self.walls.symmetry:
            from .build import symmetry, vessel
            periodic = [int(any(a == d for a, _, _ in self.walls.periodic)) for d in range(3)]
            SymmetryPlanes(symmetry(self), dim, periodic)
            vessel(self)
        return self

    def _check_wall_motions(self, protocol):
        """ValueError when the engine cannot move a wall as the protocol or a wall of
        the config asks (hard grains have no servo, rigid ones no piston yet)."""
        kind = self.engine.kind
        offered = engines.ENGINES[kind].wall_motions
        asked = {m: f"protocol {self.protocol.kind}"
                 for m in protocol.wall_motions(self.protocol)}
        for where, walls in (("planes", self.walls.planes), ("segments", self.walls.segments)):
            for k, w in enumerate(walls):
                asked.setdefault(w.motion.kind, f"walls.{where}[{k}]")
        for motion, who in asked.items():
            if motion not in offered:
                able = [e.kind for e in engines.ENGINES.values() if motion in e.wall_motions]
                raise ValueError(f"engine.kind = {kind!r} offers no {motion} walls, which "
                                 f"{who} needs; engines that do: {', '.join(able)}")

    @model_validator(mode="after")
    def _unused_material_fields(self):
        """Warn of material fields the user set that no chosen contact law reads (a
        Young's modulus under the linear spring, friction with no tangential law): they
        would be ignored without a word.  A field set to its default is no choice: a
        resolved config (dumps, a sweep's points) writes every default out.  Engines
        that do not read the contact laws (rigid grains) are not checked."""
        if not engines.ENGINES[self.engine.kind].contact_laws:
            return self
        laws = {mode: getattr(self.contact, mode) for mode in registry.MODES}
        read = material_fields(c for mode, name in laws.items()
                               for c in registry.get(mode, name).columns)
        unread = material_fields(registry.COL) - read
        chosen = ", ".join(f"{mode} {name}" for mode, name in laws.items())
        for m in self.materials:
            fields = [f for f in MaterialSection.model_fields if f in unread
                      and f in m.model_fields_set
                      and getattr(m, f) != MaterialSection.model_fields[f].default]
            if fields:
                warnings.warn(f"material {m.name!r}: {', '.join(fields)} set but not read "
                              f"by the contact laws ({chosen})")
        return self

    def material_index(self, name):
        """Position of material ``name`` in ``materials``."""
        return [m.name for m in self.materials].index(name)
