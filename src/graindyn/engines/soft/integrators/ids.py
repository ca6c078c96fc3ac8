"""Integrator names, integer ids, force evaluations per step and history slots.

The one table of integrators: everything else (the compiled dispatch, Simulation's
history arrays, the study) is generated from ``SCHEMES``.  An integrator's history is
``history[slot, grain, component]``: its translational slots first, then the same
number of rotational ones (named with the prefix ``angular_``).
"""
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Scheme:
    """name (config key), force evaluations per step, history slot names, reference;
    start_sweeps: forward-and-back sweeps that estimate higher derivatives at start-up
    (Simulation._start_derivatives), 0 for schemes that start exactly on their own."""

    name: str
    stages: int
    slots: tuple[str, ...]
    reference: str
    start_sweeps: int = 0


SCHEMES = (
    Scheme("velocity_verlet", 1, (),
           "Perez Eq. 27-30: velocity Verlet with velocity predictor (modified VV)"),
    Scheme("velocity_verlet_plain", 1, (), "Perez Eq. 24-26: velocity Verlet"),
    Scheme("verlet", 1, ("verlet_displacements",),
           "Verlet position form r(t+dt) = 2 r(t) - r(t-dt) + a dt^2 (Oquendo ref. 17)"),
    Scheme("leap_frog", 1, ("half_step_velocities",),
           "leap-frog; rotation: Omelyan's quaternion leap-frog, Oquendo Eq. 16-18"),
    Scheme("optimized_velocity_verlet", 2, (),
           "Oquendo Eq. 11-15 (Omelyan, Mryglod & Folk), xi = 0.1931833275037836"),
    Scheme("beeman", 1, ("previous_accelerations", "step_start_velocities"),
           "Perez Eq. 31-34: Beeman for velocity-dependent forces"),
    Scheme("gear3", 1, (),
           "Karrech Eq. 2-4: 3-value Gear predictor-corrector, c = (0, 1, 1)"),
    Scheme("gear5", 1, ("jerks", "snaps"),
           "Gear 5-value predictor-corrector for r'' = f (Oquendo's fifth order, their "
           "ref. 17): c = (19/120, 3/4, 1, 1/2, 1/12)", 3),
    Scheme("gear6", 1, ("jerks", "snaps", "crackles"),
           "Perez Eq. 35-38: 6-value Gear predictor-corrector", 3),
)
NAMES = tuple(s.name for s in SCHEMES)
(VELOCITY_VERLET, VELOCITY_VERLET_PLAIN, VERLET, LEAP_FROG, OPTIMIZED_VELOCITY_VERLET, BEEMAN,
 GEAR3, GEAR5, GEAR6) = range(len(SCHEMES))
STAGES = np.array([s.stages for s in SCHEMES], dtype=np.int64)
# translational history slots per scheme; the rotational ones follow at +SLOTS[k]
SLOTS = np.array([len(s.slots) for s in SCHEMES], dtype=np.int64)


def integrator_id(name):
    """Integer id of an integrator; ValueError naming the choices otherwise."""
    if name not in NAMES:
        raise ValueError(f"unknown integrator {name!r}; choose one of {list(NAMES)}")
    return NAMES.index(name)


def history_names(name):
    """Names of the history slots of integrator ``name``, translational then angular."""
    slots = SCHEMES[integrator_id(name)].slots
    return slots + tuple("angular_" + s for s in slots)
