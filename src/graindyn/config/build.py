"""From a validated Config to what a run is made of: materials, contact model, walls,
the container (protocols.Vessel), the protocol, the grains inserted into the container
and the engine (engines.ENGINES[engine.kind]).  Compiles nothing."""
import math

import numpy as np

from ..core.species import ContactModel, Material
from ..core.state import State, sample_radii
from ..core.symmetry import Symmetry
from ..core.walls import Cylinder, Motion, Periodic, Plane, Segment, box
from ..engines import ENGINES, Setup
from ..protocols import PROTOCOLS, Vessel
from ..protocols.prepare import fill
from .load import ConfigError
from .models import BoxContainer, Config


def materials(config: Config):
    """The Material objects, in config order (their index is the material id)."""
    return [Material(**m.model_dump()) for m in config.materials]


def contact_model(config: Config):
    """The ContactModel with the pair overrides by material index."""
    c = config.contact
    overrides = {tuple(config.material_index(m) for m in o.materials): dict(o.values)
                 for o in c.overrides}
    return ContactModel(c.normal, c.damping, c.tangential, c.rolling, c.twisting,
                        c.limit_damping, overrides)


def walls(config: Config):
    """The container's walls plus the extra planes and segments, and the periodic
    directions."""
    w = config.walls
    default = config.material_index(w.material)
    out = []
    box_ = w.container
    if isinstance(box_, BoxContainer):
        out += box(box_.lo, box_.hi, default, box_.open_top, config.run.dim)
    elif box_ is not None:
        cx, cy = box_.center
        out.append(Plane((cx, cy, 0.0), (0, 0, 1), default, name="bottom",
                         area=math.pi * box_.radius**2))
        out.append(Cylinder((cx, cy, 0.0), (0, 0, 1), box_.radius, default, name="side",
                            area=2 * math.pi * box_.radius * box_.height))
    for p in w.planes:
        material = default if p.material is None else config.material_index(p.material)
        out.append(Plane(p.point, p.normal, material, Motion(**p.motion.model_dump()),
                         p.name, p.area))
    for s in w.segments:
        material = default if s.material is None else config.material_index(s.material)
        out.append(Segment(tuple(s.start), tuple(s.end), material,
                           Motion(**s.motion.model_dump()), s.name, s.area,
                           (0.0, 0.0, 0.0) if s.edge is None else tuple(s.edge), s.ends))
    return out, [Periodic(a, lo, hi) for a, lo, hi in w.periodic]


def setup(config: Config, made_protocol=None):
    """The engines.Setup of ``config``: its walls as ``made_protocol`` makes them of the
    container's and the config's own (Protocol.walls)."""
    planes, periodic = walls(config)
    if made_protocol is not None:
        index = lambda name: config.material_index(name or config.walls.material)  # noqa: E731
        planes = made_protocol.walls(planes, index)
    return Setup(materials(config), contact_model(config), planes, periodic,
                 config.run.gravity, config.run.backend, symmetry(config))


def symmetry(config: Config):
    """The symmetry planes of the config (core.symmetry.Symmetry), each at its ``at`` or
    at the container's centre along its axis."""
    box_ = config.walls.container
    if isinstance(box_, BoxContainer):
        middle = [0.5 * (a + b) for a, b in zip(box_.lo, box_.hi)]
    elif box_ is not None:
        middle = list(box_.center)
    else:
        middle = []
    out = []
    for k, s in enumerate(config.walls.symmetry):
        axis = "xyz".index(s.axis)
        if s.at is None and axis >= len(middle):
            raise ValueError(f"walls.symmetry[{k}]: give its coordinate ``at`` (no "
                             f"container centre along {s.axis})")
        out.append(Symmetry(axis, middle[axis] if s.at is None else s.at, s.side))
    return tuple(out)


def vessel(config: Config):
    """The container as protocols see it (protocols.Vessel)."""
    box_ = config.walls.container
    if isinstance(box_, BoxContainer):
        whole = Vessel.box(box_.lo, box_.hi, box_.open_top, config.run.dim)
    else:
        whole = Vessel.cylinder(box_.center, box_.radius, box_.height)
    return whole.mirrored(symmetry(config))


def protocol(config: Config):
    """The run's protocol (protocols.PROTOCOLS[protocol.kind]) in its container."""
    made = PROTOCOLS[config.protocol.kind](config.protocol, vessel(config))
    made.title = config.run.name
    made.seed = config.run.seed
    return made


def engine(config: Config, state, made_protocol):
    """The engine of ``config`` (engine.kind) around ``state``, with the walls of the
    container, of the config and of ``made_protocol``."""
    return ENGINES[config.engine.kind].build(state, setup(config, made_protocol),
                                             config.engine)


def sample(config: Config, made_protocol, rng):
    """The grains of ``config`` drawn with ``rng`` and put into the protocol's container
    (prepare.fill, with the protocol's insertion settings, kept apart across the
    config's periodic directions): a State."""
    radii = grain_radii(config, rng)
    positions, radii, velocities = fill(made_protocol.vessel, radii, rng,
                                        periodic=config.walls.periodic,
                                        **config.protocol.fill_settings())
    material = config.material_index(config.grains.material)
    return State.create(positions, radii, config.materials[material].density,
                        dim=config.run.dim, materials=np.full(radii.size, material),
                        velocities=velocities)


def check_time_step(config: Config):
    """The engine's check of a grain of the smallest diameter (engines.EngineKind.check:
    the time-step report); ConfigError when the engine's settings cannot run it."""
    d = config.grains.diameter.smallest()
    grain = config.material_index(config.grains.material)
    mats = materials(config)
    state = State.create(np.zeros((1, 3)), [0.5 * d], mats[grain].density,
                         dim=config.run.dim, materials=[grain])
    try:
        return ENGINES[config.engine.kind].check(state, setup(config), config.engine)
    except (ValueError, ZeroDivisionError) as err:
        raise ConfigError(str(err)) from None


def grain_radii(config: Config, rng):
    """Radii [m] drawn from the config's diameter distribution."""
    g = config.grains
    return sample_radii(g.count, g.diameter.distribution, rng, **g.diameter.as_kwargs())
