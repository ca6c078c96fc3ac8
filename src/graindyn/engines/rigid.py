"""What the two engines of rigid grains share (event_driven: hard grains collision by
collision; contact_dynamics: rigid grains with non-smooth contact laws): grains that
store no elastic energy, gravity kept in three slots of the engine's clock, the
changes by hand of core.engine.Engine that touch only the grains' state, and the test
of a run's stop condition on the grains (stop_status)."""
import math

import numpy as np

from .._jit import kernel
from ..core.engine import checked_gravity, gravitational_energy, kinetic_energy
from ..core.triggers import ENERGY_RATIO_BELOW, MAX_SPEED_BELOW

# what a stretch of a rigid engine's run ends with (the soft engine's loop uses the
# same codes, and 2 for arrays that must grow)
DONE, CONDITION, NAN = 0, 1, 3


def rigid_energies(state, gravity, dissipated_normal, dissipated_tangential, wall_work):
    """The energies of core.engine.ENERGIES [J] of grains that store no elastic energy
    (rigid or hard grains): kinetic, rotational and gravitational of the free grains,
    elastic 0, and the dissipation and wall work an engine accumulated."""
    translational, rotational = kinetic_energy(state)
    return {"kinetic": translational, "rotational": rotational,
            "gravitational": gravitational_energy(state, gravity), "elastic": 0.0,
            "dissipated_normal": float(dissipated_normal),
            "dissipated_tangential": float(dissipated_tangential),
            "wall_work": float(wall_work)}


@kernel
def stop_status(velocities, angular_velocities, positions, masses, inertias, fixed,
                gravity, kind, value):
    """NAN when some position or velocity is not finite, CONDITION when the stop
    condition ``kind`` (core.triggers: largest speed below ``value`` [m/s], or kinetic
    over gravitational energy above the lowest free grain at most ``value``) holds."""
    vmax2 = 0.0
    kinetic = 0.0
    g = math.sqrt(gravity[0] ** 2 + gravity[1] ** 2 + gravity[2] ** 2)
    low = math.inf
    for i in range(masses.size):
        for d in range(3):
            if not (math.isfinite(positions[i, d]) and math.isfinite(velocities[i, d])):
                return NAN
        if fixed[i]:
            continue
        v2 = velocities[i, 0] ** 2 + velocities[i, 1] ** 2 + velocities[i, 2] ** 2
        w2 = angular_velocities[i, 0] ** 2 + angular_velocities[i, 1] ** 2 \
            + angular_velocities[i, 2] ** 2
        vmax2 = max(vmax2, v2)
        kinetic += 0.5 * masses[i] * v2 + 0.5 * inertias[i] * w2
        if g > 0.0:
            low = min(low, -(positions[i, 0] * gravity[0] + positions[i, 1] * gravity[1]
                             + positions[i, 2] * gravity[2]) / g)
    if kind == MAX_SPEED_BELOW and math.sqrt(vmax2) < value:
        return CONDITION
    if kind == ENERGY_RATIO_BELOW and g > 0.0:
        potential = 0.0
        for i in range(masses.size):
            if not fixed[i]:
                h = -(positions[i, 0] * gravity[0] + positions[i, 1] * gravity[1]
                      + positions[i, 2] * gravity[2]) / g
                potential += masses[i] * g * (h - low)
        if kinetic <= value * potential:
            return CONDITION
    return DONE


class RigidGrains:
    """Mixin of the rigid engines.  The engine has ``state`` (core.state.State),
    ``clock`` (its float64 slots) and ``relocate``, and names its clock slots in
    ``GRAVITY_SLOTS`` (the first of three: g_x, g_y, g_z [m/s^2]) and ``LOSS_SLOTS``
    (normal and tangential dissipation and wall work since the start [J])."""

    GRAVITY_SLOTS: int
    LOSS_SLOTS: tuple

    @property
    def gravity(self):
        """Gravitational acceleration (3,) [m/s^2] (a copy); acts from the next event or
        step on."""
        return self.clock[self.GRAVITY_SLOTS:self.GRAVITY_SLOTS + 3].copy()

    @gravity.setter
    def gravity(self, value):
        self.clock[self.GRAVITY_SLOTS:self.GRAVITY_SLOTS + 3] = checked_gravity(
            value, self.state.dim)

    def energies(self):
        """The energies of core.engine.ENERGIES [J] (rigid_energies): kinetic,
        rotational and gravitational of the free grains, elastic 0, the dissipation
        split and the wall work the engine accumulates."""
        normal, tangential, wall_work = (self.clock[k] for k in self.LOSS_SLOTS)
        return rigid_energies(self.state, self.gravity, normal, tangential, wall_work)

    def kick(self, indices, delta_v):
        """Add ``delta_v`` [m/s] to the velocities of grains ``indices``
        (engine.Engine.kick)."""
        self.state.kick(indices, delta_v)

    def hold(self, indices):
        """Stop grains ``indices`` and hold them in place (engine.Engine.hold): obstacles
        of infinite mass to the others, out of the energies, until ``release``."""
        self.state.stop(indices)

    def release(self, indices, positions, velocities, angular_velocities=None):
        """Free held grains ``indices`` at ``positions`` with ``velocities``, as
        ``relocate`` puts them (engine.Engine.release)."""
        self.relocate(indices, positions, velocities, angular_velocities)
        self.state.fixed[np.asarray(indices, dtype=np.int64).reshape(-1)] = 0
