"""From a validated Config to the engine's objects: materials, contact model, walls and
the Simulation keyword arguments.  Builds nothing that compiles."""
import math

import numpy as np

from ..core.species import ContactModel, Material
from ..core.state import State, sample_radii
from ..core.walls import Cylinder, Motion, Periodic, Plane, box
from ..engines.soft.timestep import time_step_report
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
    """The container's walls plus the extra planes, and the periodic directions."""
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
    return out, [Periodic(a, lo, hi) for a, lo, hi in w.periodic]


def simulation_kwargs(config: Config):
    """Keyword arguments of Simulation other than the state."""
    planes, periodic = walls(config)
    i = config.engine
    return {"materials": materials(config), "model": contact_model(config), "walls": planes,
            "periodic": periodic, "gravity": config.run.gravity, "dt": i.dt, "skin": i.skin,
            "integrator": i.integrator, "allow_large_dt": i.allow_large_dt,
            "overlap_limit": i.overlap_limit, "check_interval": i.check_interval,
            "orientations": i.orientations, "backend": config.run.backend}


def check_time_step(config: Config):
    """The time-step report for the smallest grain of the config; ConfigError naming
    engine.dt when the step is above the safe fraction of the contact time."""
    d = config.grains.diameter.smallest()
    grain = config.material_index(config.grains.material)
    mats = materials(config)
    state = State.create(np.zeros((1, 3)), [0.5 * d], mats[grain].density,
                         dim=config.run.dim, materials=[grain])
    try:
        report = time_step_report(state, mats, contact_model(config), config.engine.dt,
                                  config.engine.integrator)
    except (ValueError, ZeroDivisionError) as err:
        raise ConfigError(f"cannot work out a time step: {err}") from None
    dt = config.engine.dt
    if dt is not None and report["fraction"] > report["max_fraction"] \
            and not config.engine.allow_large_dt:
        raise ConfigError(
            f"engine.dt = {dt:.3g} s is {report['fraction']:.2f} of the "
            f"{report['criterion']} {report['critical_time_s']:.3g} s of the smallest grain"
            + (f" ({report['limit']})" if "limit" in report else "") + "; "
            f"allowed: dt <= {report['max_fraction'] * report['critical_time_s']:.3g} s "
            f"(suggested {report['suggested_dt_s']:.3g} s), or set "
            "engine.allow_large_dt = true")
    return report


def grain_radii(config: Config, rng):
    """Radii [m] drawn from the config's diameter distribution."""
    g = config.grains
    return sample_radii(g.count, g.diameter.distribution, rng, **g.diameter.as_kwargs())
