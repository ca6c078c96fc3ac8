"""The engine interface: what every engine offers to the layers above it (protocols,
analysis, outputs), whatever its method of moving grains.

Today's engine is the soft-particle DEM of ``Simulation`` (time steps, overlapping
grains).  An event-driven engine (hard grains, collision by collision) and a contact
dynamics engine (rigid grains, contact forces from the non-smooth laws) are to offer
the same interface, so nothing here speaks of time steps, skins, neighbour lists or
overlaps: durations are simulated time, contacts are what they carry, walls move by
physical laws.

Conventions (README): SI units; the contact normal n points from grain j to grain i
(from the wall to the grain for a wall contact) and forces are those on grain i
(on the grain); a positive normal force pushes the two apart.
"""
from typing import NamedTuple, Protocol, runtime_checkable

import numpy as np

from .state import State
from .walls import Motion, Walls

# the energies every engine reports [J], and what each is
ENERGIES = {
    "kinetic": "translational kinetic energy of the free grains, sum m v^2/2",
    "rotational": "rotational kinetic energy of the free grains, sum I w^2/2",
    "gravitational": "-sum m g.r of the free grains (zero at the origin)",
    "elastic": "energy stored in the contacts (zero for rigid grains)",
    "dissipated_normal": "energy dissipated by the normal contact law since the start",
    "dissipated_tangential": "energy dissipated by friction and the tangential, rolling "
                             "and twisting laws since the start",
    "wall_work": "work done on the grains by moving walls since the start",
}


def checked_gravity(value, dim):
    """``value`` as a gravity vector (3,) [m/s^2] for grains in ``dim`` D: what every
    engine's gravity setter takes; ValueError unless a finite 3-vector with zero z
    component in 2D."""
    gravity = np.asarray(value, dtype=np.float64)
    if gravity.shape != (3,) or not np.all(np.isfinite(gravity)) \
            or (dim == 2 and gravity[2] != 0):
        raise ValueError(f"gravity must be a finite 3-vector [m/s^2], with zero z component "
                         f"in 2D, got {value}")
    return gravity


def kinetic_energy(state):
    """(translational, rotational) kinetic energy of the free grains [J]."""
    free = state.fixed == 0
    v2 = np.einsum("ij,ij->i", state.velocities, state.velocities)
    w2 = np.einsum("ij,ij->i", state.angular_velocities, state.angular_velocities)
    return (float(0.5 * np.sum(state.masses[free] * v2[free])),
            float(0.5 * np.sum(state.inertias[free] * w2[free])))


def gravitational_energy(state, gravity):
    """-sum m g.r of the free grains [J] (zero at the origin)."""
    free = state.fixed == 0
    return float(-np.sum(state.masses[free] * (state.positions[free] @ np.asarray(gravity))))


def copy_into(targets, arrays):
    """Put the snapshot ``arrays`` (name -> array) into an engine's own ``targets``
    (name -> array, the engine's arrays of those names), in place; ValueError naming
    what is missing or does not fit (an engine's restore)."""
    missing = [k for k in targets if k not in arrays]
    if missing:
        raise ValueError(f"snapshot lacks {missing}")
    for name, target in targets.items():
        value = np.asarray(arrays[name])
        if value.shape != target.shape or value.dtype != target.dtype:
            raise ValueError(f"snapshot array {name}: {value.dtype}{value.shape} does not "
                             f"fit {target.dtype}{target.shape}")
        target[...] = value


class SimulationError(RuntimeError):
    """A run stopped because the physics broke down (NaN, excessive overlap)."""


class OverlapError(SimulationError):
    """Some overlap exceeded ``overlap_limit`` of the smaller radius: the state is finite,
    but the load is beyond what the contact law describes."""


def _whole_force(contacts):
    """(K, 3) [N] the whole force of each contact on its grain i (or grain):
    normal_force n + tangential_force."""
    return contacts.normal_force[:, None] * contacts.normal + contacts.tangential_force


class Contacts(NamedTuple):
    """The touching grain pairs (K of them) with what they carry.

    i, j : (K,) int64 grain indices;  n below points from j to i.
    branch_i, branch_j : (K, 3) [m] from the centre of i (of j) to the contact point;
      branch_j - branch_i = r_i - r_j, the minimum image across periodic directions.
    normal_force : (K,) [N] the force on i along n, positive when it pushes i away from j.
    tangential_force : (K, 3) [N] the force on i in the contact plane.
    normal : (K, 3) unit normal n.
    The force on j is minus the force on i (Newton's third law).
    """

    i: np.ndarray
    j: np.ndarray
    branch_i: np.ndarray
    branch_j: np.ndarray
    normal_force: np.ndarray
    tangential_force: np.ndarray
    normal: np.ndarray

    force = property(_whole_force)


class WallContacts(NamedTuple):
    """The touching grain-wall contacts (K of them) with what they carry.

    grain, wall : (K,) int64 grain and wall indices;  n below points from the wall to
      the grain.
    branch : (K, 3) [m] from the centre of the grain to the contact point on the wall.
    normal_force : (K,) [N] the force on the grain along n, positive when it pushes the
      grain away from the wall.
    tangential_force : (K, 3) [N] the force on the grain in the contact plane.
    normal : (K, 3) unit normal n.
    """

    grain: np.ndarray
    wall: np.ndarray
    branch: np.ndarray
    normal_force: np.ndarray
    tangential_force: np.ndarray
    normal: np.ndarray

    force = property(_whole_force)


class ImageContacts(NamedTuple):
    """The touching contacts (K of them) between grains and the mirror images of grains
    that symmetry planes make (core/symmetry.py), each seen from the grain it acts on.

    grain : (K,) int64 the grain;  image_of : (K,) int64 the grain whose image it
      touches (itself, for its own image);  mask : (K,) int64 the mirrored axes (bit d
      for axis d).
    branch : (K, 3) [m] from the centre of the grain to the contact point.
    normal_force, tangential_force, normal : as for Contacts, n from the image to the
      grain.
    """

    grain: np.ndarray
    image_of: np.ndarray
    mask: np.ndarray
    branch: np.ndarray
    normal_force: np.ndarray
    tangential_force: np.ndarray
    normal: np.ndarray

    force = property(_whole_force)


@runtime_checkable
class Engine(Protocol):
    """What the layers above an engine may use of it.  The engine owns its arrays:
    the layers above read ``state`` and ``walls`` and change them only through the
    methods here (relocate, kick, set_motion, set_servo, place_wall, gravity), which keep
    the engine's own bookkeeping (contact histories, lists, wall references) right.

    Walls (``wall`` arguments) are given by index or by name (Walls.index).
    """

    state: State
    """The grains (core.state.State): positions [m], velocities [m/s], radii [m]..."""

    walls: Walls
    """The walls (core.walls.Walls): geometry, offset [m] and velocity [m/s] of each
    wall, the force the grains exert on it [N] (Walls.normal_force, Walls.stress), its
    prescribed motion (Walls.motion_of)."""

    rigid: bool
    """Whether the grains are rigid: no contact elasticity, so no elastic energy and no
    overlap (event-driven and contact dynamics engines); False for soft grains."""

    @property
    def time(self) -> float:
        """Simulated time [s]."""

    @property
    def gravity(self) -> np.ndarray:
        """Gravitational acceleration (3,) [m/s^2] (a copy); setting it acts from the
        next step on, ValueError unless a finite 3-vector (in 2D with zero z)."""

    @gravity.setter
    def gravity(self, value) -> None: ...

    def run(self, *, time=None, until=None, every=(), between=None) -> str:
        """Advance the simulated time by ``time`` [s] (required, an upper bound also with
        ``until``): the run ends at the first instant the engine stops at that is not
        before time + ``time`` (a time-stepping engine: the end of the step that reaches
        it), or earlier when the stop condition ``until`` (core.triggers.MaxSpeedBelow,
        EnergyRatioBelow) holds.

        every : (core.triggers.Periodic(time=...), callback(engine)) pairs, each
          callback run every ``time`` seconds of simulated time.
        between : callback(engine) run at each pause of the engine (at least as often as
          ``every`` fires); returning True stops the run.
        Returns "done", "condition" (``until`` held) or "stopped" (``between``); raises
        core.engine.SimulationError when the physics breaks down (OverlapError: an
        overlap beyond what the contact law describes, for engines that let grains overlap)."""

    def contacts(self) -> Contacts:
        """The touching grain pairs now (Contacts)."""

    def wall_contacts(self) -> WallContacts:
        """The touching grain-wall contacts now (WallContacts)."""

    def energies(self) -> dict:
        """Every energy of ENERGIES by name [J] (floats); their balance, kinetic +
        rotational + gravitational + elastic + dissipated - wall work, stays constant
        (analysis.energy.energy_budget)."""

    def snapshot(self) -> dict:
        """Every mutable array of the run by name (copies); ``restore`` of it into an
        engine built from the same inputs continues the run bit for bit."""

    def restore(self, arrays) -> None:
        """Put a ``snapshot`` back; ValueError naming what is missing or does not fit."""

    def relocate(self, indices, positions, velocities, angular_velocities=None) -> None:
        """Move grains ``indices`` to ``positions`` (K, 3) [m] with ``velocities`` (K, 3)
        [m/s] and ``angular_velocities`` (K, 3) [rad/s] (None: zero), e.g. to re-inject
        grains that left a silo.  The grains arrive without any memory of the contacts
        they had (their tangential springs and other contact history are forgotten) and
        meet their new neighbours and walls from the next step on."""

    def kick(self, indices, delta_v) -> None:
        """Add ``delta_v`` ((3,) or (K, 3) [m/s]) to the velocities of grains ``indices``
        at once, keeping their places, spins and contacts (a tap that sets the whole
        material moving with its container)."""

    def hold(self, indices) -> None:
        """Stop grains ``indices`` and hold them in place: fixed obstacles to the others,
        left out of the energies, until released (a reservoir of grains to rain in)."""

    def release(self, indices, positions, velocities, angular_velocities=None) -> None:
        """Free held grains ``indices`` at ``positions`` with ``velocities``, arriving as
        ``relocate`` puts grains."""

    def set_motion(self, wall, motion: Motion) -> None:
        """Prescribe the motion (core.walls.Motion) of ``wall`` from now on: "fixed"
        stops it; "velocity" and "sinusoid" start from where the wall is now, at the
        motion's ``start`` [s] (simulated time) or now if that has passed; "servo" as
        set_servo; "piston" makes it a wall of a mass driven by an applied force and by
        the grains (core.walls), from its velocity now."""

    def set_servo(self, wall, *, force=None, stress=None, gain=None, time_constant=None,
                  stiffness=None, max_speed=None, direction=None) -> None:
        """Make ``wall`` a stress-controlled wall, or change the settings of one: it moves
        along ``direction`` (a 3-vector into the grains) at

            v = clamp(g (F_target - F), -v_max, v_max),

        F [N] the force the grains exert against ``direction``.  The target F_target is
        ``force`` [N] or ``stress`` [Pa] times the wall's area; the gain g [m/(N s)] is
        ``gain``, or 1/(``stiffness`` [N/m] ``time_constant`` [s]): against a sample of
        that stiffness the force error then decays as exp(-t/time_constant).
        v_max = ``max_speed`` [m/s].  Settings not given keep their values on a wall that
        is a servo already and are required otherwise."""

    def place_wall(self, wall, offset) -> None:
        """Put ``wall`` at ``offset`` (3,) [m] from the place it was built at, at once
        (the grains in its way are not swept along: place it where none is)."""
