"""Relaxation of a configuration by minimising Karrech et al.'s functional (Eq. 24-29).

An extrapolated configuration (analysis/settlement.py) can hold excessive overlaps
that would blow up the next molecular-dynamics run.  Karrech et al. (Sec. 4) correct it
by minimising over the grain positions, with the frontier grains fixed, the potential
energy whose stationary points are the static equilibria of Eq. 1 (the virtual-work
statement Eq. 24-28 with a = 0):

    F(u) = sum_pairs psi(delta_ab) + sum_grain-wall psi(delta_bw)
           - sum_b m_b g . u_b - sum_b F_b . u_b                               (Eq. 29)

u_b = r_b - r_b^0 [m] the displacement from the given configuration, g [m/s^2] gravity,
F_b [N] the applied loads.  Eq. 29 prints the work terms with a + sign; they are the
potential of the external forces, so they enter with a minus sign here (gravity then
pulls grains down, as it must).  The contact potential is Karrech's
psi = k_n/(gamma + 1) delta^(gamma + 1) with gamma = 3/2 and k_n = 4/3 E* sqrt(R*), so
that -d psi/d delta is exactly the Hertz force 4/3 E* sqrt(R*) delta^(3/2) of the soft
engine (physics/normal.py: psi = 8/15 E* sqrt(R*) delta^(5/2)), with E* and R* mixed as
the engine mixes them (core/species.py: 1/E* = (1 - nu_a^2)/E_a + (1 - nu_b^2)/E_b,
1/R* = 1/R_a + 1/R_b; a wall has R = infinity, so R* = R_b, and the wall's material).
Only elastic normal contacts enter: in a quasi-static relaxation friction does no work
(Karrech's ||F_t|| <= mu F_n argument), so the minimum is the frictionless equilibrium.
With symmetry planes (core/symmetry.py) the contacts of grains with mirror images enter
with half their potential each, as in the dynamics (image_contacts.py): the gradient
on grain i of (i, j') and (j, i') together is then the full image force on i, and a
grain's own image holds it on its side of the plane.

Candidate pairs and grain-wall contacts come from the core's neighbour search
(core/neighbors.rebuild, with no history), listed within R_a + R_b + skin; the lists
are rebuilt whenever a grain has moved more than half the skin since the last build,
so every overlapping pair is always listed and the functional is exact.

Minimiser: L-BFGS (scipy.optimize.minimize, method L-BFGS-B, without bounds) on the
compiled functional and its exact gradient.  It is chosen over FIRE because the Hertz
contacts are stiff (about 1e5-1e9 N/m from equilibrium to the excessive overlaps): FIRE
is a damped dynamics whose step is bounded by the stiffest contact, thousands of
steps for a bed, while the quasi-Newton model of L-BFGS adapts to the curvature and
converges in tens to hundreds of iterations.  Variables are scaled: displacements in
units of the mean radius L, the functional in units of W L, with W the mean grain
weight at standard gravity (9.81 m/s^2), so the gradient is the residual force in
grain weights and ``force_tolerance`` is the largest residual force component
allowed, in weights.  The functional's precision (about 1e-16 of its value) limits how
small a residual a line search can still resolve: about 2e-6 W on the nine-grain
cell of the tests, hence the default tolerance of 1e-5 W.
"""
from typing import NamedTuple

import math

import numpy as np
from scipy.optimize import minimize

from ..._jit import kernel, scalar
from ...core.neighbors import min_image, rebuild
from ...core.species import ContactModel
from ...core.symmetry import MASKS, SymmetryPlanes, image_separation, rebuild_images
from ...core.walls import Walls, wall_distance
from ...physics.normal import normal_hertz_energy, normal_hertz_stiffness
from ...physics.registry import COL

STANDARD_GRAVITY = 9.81     # [m/s^2], the force unit W = m g of the scaled variables


class Overlaps(NamedTuple):
    """Distribution of the overlaps of the contacts (grain pairs and grain-wall) with
    delta > 0, relative to the smaller radius (the grain's radius against a wall) [-];
    ``largest`` is the largest overlap in metres; ``values`` every contact's relative
    overlap (pairs, then grain-wall contacts), for a histogram (Karrech Fig. 9)."""

    count: int
    max: float
    mean: float
    p50: float
    p90: float
    p99: float
    largest: float
    values: np.ndarray


class Relaxation(NamedTuple):
    """The result of ``relax``.

    positions : (N, 3) [m] relaxed positions (the fixed grains where they were)
    functional_before, functional_after : Eq. 29 [J] at the start (u = 0: the contact
      energy) and at the end
    functional_trace : (iterations + 1,) [J] Eq. 29 at the start and after each
      iteration (non-increasing: each L-BFGS step satisfies the Wolfe conditions; one
      more evaluation per iteration, not counted in ``evaluations``)
    iterations, evaluations : L-BFGS iterations and functional evaluations
    rebuilds : neighbour-list builds (the first included)
    converged : True when the largest residual force component fell below the tolerance;
      message : the minimiser's
    overlaps_before, overlaps_after : Overlaps
    residual_force : largest net force [N] on a free grain after relaxation
    residual_over_weight : the largest ratio of a free grain's net force to its weight
      m |g| (nan without gravity)
    largest_contact_force : [N] after relaxation (Hertz, pairs and walls)
    """

    positions: np.ndarray
    functional_before: float
    functional_after: float
    functional_trace: np.ndarray
    iterations: int
    evaluations: int
    rebuilds: int
    converged: bool
    message: str
    overlaps_before: Overlaps
    overlaps_after: Overlaps
    residual_force: float
    residual_over_weight: float
    largest_contact_force: float


@scalar
def _separation(positions, i, j, periodic_flag, periodic_length):
    """r_i - r_j [m] at ``positions``, the minimum image along periodic axes."""
    return (min_image(positions[i, 0] - positions[j, 0], periodic_flag[0], periodic_length[0]),
            min_image(positions[i, 1] - positions[j, 1], periodic_flag[1], periodic_length[1]),
            min_image(positions[i, 2] - positions[j, 2], periodic_flag[2], periodic_length[2]))


@kernel
def functional(positions, reference, radii, masses, materials, youngs, gravity, loads, anchor,
               free,
               start, partners, periodic_flag, periodic_length,
               wall_start, wall_ids, wall_kind, wall_geometry, wall_offset, wall_material,
               image_start, image_codes, mirror_at, allowed, excess, allowed_offset,
               excess_walls, gradient):
    """Eq. 29 [J] at ``positions`` (N, 3) [m], displacements from ``reference``; writes
    its gradient (N, 3) [N] (minus the net force on each grain; 0 on grains with
    free[b] == 0).  youngs[a, b]: E* [Pa] of materials a, b; gravity (3,) [m/s^2];
    loads (N, 3) [N]; anchor (N,) [N/m]: springs k_b |u_b|^2 / 2 holding each grain to
    its reference place (0: none); start, partners: the pair list (CSR, i < j); wall_start,
    wall_ids: the grain-wall candidates; the wall arrays as in core/walls.py;
    image_start, image_codes, mirror_at: the image candidates of the symmetry planes
    (core/symmetry.py), half the potential of each, its whole force on its grain.
    With ``excess`` True a grain pair (or image pair) enters only with the overlap
    beyond the one it has at the ``allowed`` positions (N, 3) [m]: psi(delta -
    delta_allowed), the Hertz potential of the excess; with ``excess_walls`` True a
    grain-wall contact too, its allowed overlap the grain's at ``allowed`` against the
    wall at ``allowed_offset`` (W, 3) [m]."""
    n = radii.size
    energy = 0.0
    for b in range(n):
        for d in range(3):
            u = positions[b, d] - reference[b, d]
            energy += 0.5 * anchor[b] * u * u - (masses[b] * gravity[d] + loads[b, d]) * u
            gradient[b, d] = anchor[b] * u - (masses[b] * gravity[d] + loads[b, d])
    for i in range(n):
        for k in range(start[i], start[i + 1]):
            j = partners[k]
            dx, dy, dz = _separation(positions, i, j, periodic_flag, periodic_length)
            distance = math.sqrt(dx * dx + dy * dy + dz * dz)
            overlap = radii[i] + radii[j] - distance
            if excess:
                ax, ay, az = _separation(allowed, i, j, periodic_flag, periodic_length)
                overlap -= max(0.0, radii[i] + radii[j] - math.sqrt(ax * ax + ay * ay + az * az))
            if overlap <= 0.0 or distance == 0.0:
                continue
            r_eff = radii[i] * radii[j] / (radii[i] + radii[j])
            e_eff = youngs[materials[i], materials[j]]
            energy += normal_hertz_energy(overlap, r_eff, e_eff)
            force = normal_hertz_stiffness(math.sqrt(r_eff * overlap), e_eff) * overlap
            scale = force / distance            # the force pushes i along +d, j along -d
            gradient[i, 0] -= scale * dx
            gradient[i, 1] -= scale * dy
            gradient[i, 2] -= scale * dz
            gradient[j, 0] += scale * dx
            gradient[j, 1] += scale * dy
            gradient[j, 2] += scale * dz
        for k in range(wall_start[i], wall_start[i + 1]):
            w = wall_ids[k]
            dist, nx, ny, nz = wall_distance(wall_kind, wall_geometry, wall_offset, w,
                                             positions[i, 0], positions[i, 1],
                                             positions[i, 2])
            overlap = radii[i] - dist
            if excess_walls:
                dist = wall_distance(wall_kind, wall_geometry, allowed_offset, w,
                                     allowed[i, 0], allowed[i, 1], allowed[i, 2])[0]
                overlap -= max(0.0, radii[i] - dist)
            if overlap <= 0.0:
                continue
            e_eff = youngs[materials[i], wall_material[w]]
            energy += normal_hertz_energy(overlap, radii[i], e_eff)
            force = normal_hertz_stiffness(math.sqrt(radii[i] * overlap), e_eff) * overlap
            gradient[i, 0] -= force * nx
            gradient[i, 1] -= force * ny
            gradient[i, 2] -= force * nz
        for q in range(image_start[i], image_start[i + 1]):
            j = image_codes[q] // MASKS
            dx, dy, dz = image_separation(i, image_codes[q], positions, mirror_at,
                                          periodic_flag, periodic_length)
            distance = math.sqrt(dx * dx + dy * dy + dz * dz)
            overlap = radii[i] + radii[j] - distance
            if excess:
                ax, ay, az = image_separation(i, image_codes[q], allowed, mirror_at,
                                              periodic_flag, periodic_length)
                overlap -= max(0.0, radii[i] + radii[j] - math.sqrt(ax * ax + ay * ay + az * az))
            if overlap <= 0.0 or distance == 0.0:
                continue
            r_eff = radii[i] * radii[j] / (radii[i] + radii[j])
            e_eff = youngs[materials[i], materials[j]]
            energy += 0.5 * normal_hertz_energy(overlap, r_eff, e_eff)
            scale = normal_hertz_stiffness(math.sqrt(r_eff * overlap), e_eff) * overlap \
                / distance
            gradient[i, 0] -= scale * dx
            gradient[i, 1] -= scale * dy
            gradient[i, 2] -= scale * dz
    for b in range(n):
        if free[b] == 0:
            for d in range(3):
                gradient[b, d] = 0.0
    return energy


class _Lists(NamedTuple):
    start: np.ndarray
    partners: np.ndarray
    wall_start: np.ndarray
    wall_ids: np.ndarray
    image_start: np.ndarray
    image_codes: np.ndarray


def candidate_lists(positions, radii, skin, walls, symmetry=None):
    """The pairs within R_a + R_b + skin [m], the grain-wall candidates within R_b +
    skin and the image candidates of the symmetry planes ``symmetry``
    (core.symmetry.SymmetryPlanes or None), by the core's neighbour searches
    (core/neighbors.rebuild, core/symmetry.rebuild_images, no contact history kept);
    returns (start, partners, wall_start, wall_ids, image_start, image_codes) in CSR
    form."""
    n = radii.size
    pairs, candidates = 8 * n, 2 * n + 1
    while True:
        start = np.zeros(n + 1, np.int64)
        wall_start = np.zeros(n + 1, np.int64)
        partners = np.zeros(pairs, np.uint32)
        wall_ids = np.zeros(candidates, np.uint32)
        needed, wall_needed = rebuild(
            positions.copy(), radii, skin, walls.periodic_flag, walls.periodic_lo,
            walls.periodic_length, start, partners, np.zeros((pairs, 0)),
            np.zeros(n + 1, np.int64), np.zeros(pairs, np.uint32), np.zeros((pairs, 0)),
            np.zeros(n + 1, np.int64), np.zeros(pairs, np.uint32),
            walls.kind, walls.geometry, walls.offset, wall_start, wall_ids,
            np.zeros((candidates, 0)), np.zeros(n + 1, np.int64),
            np.zeros(candidates, np.uint32), np.zeros((candidates, 0)),
            np.zeros((n, 3)), np.zeros((len(walls), 3)))
        if needed <= pairs and wall_needed <= candidates:
            break
        pairs, candidates = max(pairs, int(needed)), max(candidates, int(wall_needed))
    image_start, image_codes = _image_candidates(positions, radii, skin, walls, symmetry)
    return _Lists(start, partners[:needed], wall_start, wall_ids[:wall_needed], image_start,
                  image_codes)


def _image_candidates(positions, radii, skin, walls, symmetry):
    """(start (N + 1,), codes) of the image candidates (core/symmetry.rebuild_images);
    empty without symmetry planes."""
    n = radii.size
    start = np.zeros(n + 1, np.int64)
    if not symmetry:
        return start, np.zeros(0, np.uint32)
    size = n + 1
    while True:
        codes = np.zeros(size, np.uint32)
        needed = rebuild_images(positions.copy(), radii, skin, walls.periodic_flag,
                                walls.periodic_lo, walls.periodic_length, symmetry.flag,
                                symmetry.at, start, codes, np.zeros((size, 0)),
                                np.zeros(n + 1, np.int64), np.zeros(size, np.uint32),
                                np.zeros((size, 0)))
        if needed <= size:
            return start, codes[:needed]
        size = int(needed)


def contact_overlaps(positions, radii, walls, lists, symmetry=None):
    """Overlaps [m] of the listed pairs and grain-wall candidates in contact, with the
    grains involved: (pair overlaps, pair (i, j) (P, 2), wall overlaps, wall grains,
    walls); the image contacts of the symmetry planes ``symmetry`` count among the
    pairs, (i, j) for grain i and the image of j."""
    n = radii.size
    owner = np.repeat(np.arange(n), np.diff(lists.start))
    other = lists.partners.astype(np.int64)
    separation = walls.minimum_image(positions[owner] - positions[other])
    if symmetry:
        codes = lists.image_codes.astype(np.int64)
        imaged = np.repeat(np.arange(n), np.diff(lists.image_start))
        separation = np.vstack([separation, walls.minimum_image(
            positions[imaged] - symmetry.image(positions[codes // MASKS], codes % MASKS))])
        owner = np.concatenate([owner, imaged])
        other = np.concatenate([other, codes // MASKS])
    overlap = radii[owner] + radii[other] - np.linalg.norm(separation, axis=1)
    touching = overlap > 0
    wall_owner = np.repeat(np.arange(n), np.diff(lists.wall_start))
    ids = lists.wall_ids.astype(np.int64)
    distance = walls.distances(positions[wall_owner], ids)[0] if ids.size else np.zeros(0)
    wall_overlap = radii[wall_owner] - distance
    on_wall = wall_overlap > 0
    return (overlap[touching], np.stack([owner, other], axis=1)[touching],
            wall_overlap[on_wall], wall_owner[on_wall], ids[on_wall])


def overlap_distribution(positions, radii, walls, lists, symmetry=None):
    """Overlaps of the contacts at ``positions`` (see Overlaps), image contacts
    included."""
    overlap, pair, wall_overlap, wall_grain, _ = contact_overlaps(positions, radii, walls,
                                                                  lists, symmetry)
    relative = np.concatenate([overlap / np.minimum(radii[pair[:, 0]], radii[pair[:, 1]]),
                               wall_overlap / radii[wall_grain]])
    if relative.size == 0:
        return Overlaps(0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, relative)
    p50, p90, p99 = np.percentile(relative, [50, 90, 99])
    largest = float(max(overlap.max(initial=0.0), wall_overlap.max(initial=0.0)))
    return Overlaps(int(relative.size), float(relative.max()), float(relative.mean()),
                    float(p50), float(p90), float(p99), largest, relative)


def youngs_table(materials):
    """E* [Pa] of every pair of materials, mixed as the soft engine mixes them."""
    if len(materials) == 0:
        raise ValueError("relax needs the materials of the grains and walls")
    return np.ascontiguousarray(
        ContactModel(normal="hertz").pair_table(list(materials))[:, :, COL["youngs_eff"]])


def relax(state, materials, walls=None, fixed=None, gravity=(0.0, 0.0, -9.81), loads=None,
          skin=None, force_tolerance=1e-5, max_iterations=10000, update=False,
          symmetry=(), anchor=0.0, allowed=None, allowed_walls=None):
    """Minimise the functional of Eq. 29 over the positions of the free grains.

    state : core.State (positions, radii, masses, materials);  materials : the list of
    core.Material the grains' and walls' material indices refer to;  walls : core.Walls
    or a list of walls (None: none);  fixed : (N,) bool, the frontier grains that stay
    in place (None: state.fixed != 0);  gravity : (3,) [m/s^2];  loads : (N, 3) [N]
    applied forces (None: none);  skin [m] of the candidate lists (None: 0.2 of the mean
    radius);  force_tolerance : the largest residual force component, in mean grain
    weights (module docstring);  max_iterations of L-BFGS;  update : write the relaxed
    positions into the state (velocities are left as they are) when True;  symmetry :
    core.symmetry.SymmetryPlanes or a list of Symmetry planes (module docstring);
    anchor : the stiffness of a spring holding each grain to where it starts, in its
    weight m_b 9.81 m/s^2 per mean radius [-] (0: none): with gravity off, the
    relaxation then removes the overlaps moving the grains as little as it can (the
    functional without gravity is flat wherever no grains overlap, and a first
    quasi-Newton step could throw a grain a radius away);  allowed : (N, 3) [m] a
    configuration whose overlaps between grains are kept: each pair enters with the
    Hertz potential of its overlap beyond the one it has there (None: the whole
    overlap), so that a configuration moved on from a computed one (an extrapolation)
    loses its excessive overlaps and keeps the loaded contacts it had; grain-wall
    contacts enter whole, unless ``allowed_walls`` (W, 3) [m], the walls' offsets in the
    ``allowed`` configuration, is given: then each grain-wall contact too keeps the
    overlap it has there (a bed moved on together with its loading plate keeps the
    contacts that carry the plate and its weight on the floor).  The overlaps reported
    are the whole ones.
    Returns a Relaxation.  Only the positions move: 2D states keep z = 0.  From a
    soft-engine run: ``relax(sim.state, materials, walls=sim.walls)``.
    """
    if walls is None:
        walls = Walls()
    elif not isinstance(walls, Walls):
        walls = Walls(walls)
    if not isinstance(symmetry, SymmetryPlanes):
        symmetry = SymmetryPlanes(symmetry, state.dim, walls.periodic_flag)
    n = state.n
    radii = np.ascontiguousarray(state.radii, dtype=np.float64)
    masses = np.ascontiguousarray(state.masses, dtype=np.float64)
    grain_materials = np.ascontiguousarray(state.materials, dtype=np.int64)
    wall_material = np.ascontiguousarray(walls.material, dtype=np.int64)
    used = np.concatenate([grain_materials, wall_material])
    if used.size and (used.min() < 0 or used.max() >= len(materials)):
        raise ValueError(f"material indices must be below len(materials) = {len(materials)}")
    youngs = youngs_table(materials)
    fixed = state.fixed != 0 if fixed is None else np.asarray(fixed, dtype=bool).reshape(-1)
    if fixed.shape != (n,):
        raise ValueError(f"fixed must be ({n},) booleans, got {fixed.shape}")
    free = (~fixed).astype(np.int8)
    g = np.asarray(gravity, dtype=np.float64).reshape(3)
    if not anchor >= 0:
        raise ValueError(f"anchor must be >= 0 [weights per mean radius], got {anchor}")
    springs = anchor * masses * STANDARD_GRAVITY / float(radii.mean())
    loads = np.zeros((n, 3)) if loads is None else \
        np.ascontiguousarray(np.broadcast_to(np.asarray(loads, np.float64), (n, 3)))
    skin = 0.2 * float(radii.mean()) if skin is None else float(skin)
    if not skin > 0:
        raise ValueError(f"skin must be > 0 [m], got {skin}")
    if not force_tolerance > 0:
        raise ValueError(f"force_tolerance must be > 0 [weights], got {force_tolerance}")

    reference = np.ascontiguousarray(state.positions, dtype=np.float64).copy()
    excess = allowed is not None
    allowed = reference if allowed is None else np.ascontiguousarray(allowed, dtype=np.float64)
    if allowed.shape != (n, 3):
        raise ValueError(f"allowed must be the ({n}, 3) positions [m] of a configuration, "
                         f"got {allowed.shape}")
    excess_walls = allowed_walls is not None
    if excess_walls and not excess:
        raise ValueError("allowed_walls needs allowed: the walls' offsets go with the "
                         "grains' positions of the allowed configuration")
    allowed_offset = walls.offset if allowed_walls is None else \
        np.ascontiguousarray(allowed_walls, dtype=np.float64)
    if allowed_offset.shape != walls.offset.shape:
        raise ValueError(f"allowed_walls must be the {walls.offset.shape} offsets [m] of "
                         f"the walls, got {allowed_offset.shape}")
    variable = np.zeros((n, 3), bool)
    variable[free == 1, :state.dim] = True
    length = float(radii.mean())
    weight = float(masses.mean()) * STANDARD_GRAVITY
    positions = reference.copy()
    gradient = np.zeros((n, 3))
    built = {"at": reference.copy(),
             "lists": candidate_lists(reference, radii, skin, walls, symmetry), "count": 1}

    def evaluate(at):
        if np.sqrt(((at - built["at"]) ** 2).sum(axis=1).max()) > 0.5 * skin:
            built["at"] = at.copy()
            built["lists"] = candidate_lists(at, radii, skin, walls, symmetry)
            built["count"] += 1
        lists = built["lists"]
        return functional(at, reference, radii, masses, grain_materials, youngs, g, loads,
                          springs, free, lists.start, lists.partners, walls.periodic_flag,
                          walls.periodic_length, lists.wall_start, lists.wall_ids,
                          walls.kind, walls.geometry, walls.offset, wall_material,
                          lists.image_start, lists.image_codes, symmetry.at, allowed,
                          excess, allowed_offset, excess_walls, gradient)

    def scaled(x):
        positions[variable] = reference[variable] + x * length
        energy = evaluate(positions)
        return energy / (weight * length), gradient[variable] / weight

    before = evaluate(reference)
    overlaps_before = overlap_distribution(reference, radii, walls, built["lists"], symmetry)
    trace = [before]

    def record(x):
        trace.append(scaled(x)[0] * weight * length)

    result = minimize(scaled, np.zeros(int(variable.sum())), jac=True, method="L-BFGS-B",
                      callback=record,
                      options=dict(maxiter=max_iterations, maxfun=4 * max_iterations,
                                   maxcor=20, ftol=1e-15, gtol=force_tolerance, maxls=50))
    positions[variable] = reference[variable] + result.x * length
    after = evaluate(positions)
    net = -gradient[free == 1]
    net_norm = np.linalg.norm(net, axis=1) if net.size else np.zeros(1)
    g_norm = float(np.linalg.norm(g))
    over_weight = float((net_norm / (masses[free == 1] * g_norm)).max()) \
        if g_norm > 0 and net.size else math.nan
    lists = built["lists"]
    overlap, pair, wall_overlap, wall_grain, wall_id = contact_overlaps(positions, radii,
                                                                        walls, lists,
                                                                        symmetry)
    r_eff = radii[pair[:, 0]] * radii[pair[:, 1]] / (radii[pair[:, 0]] + radii[pair[:, 1]])
    pair_force = 4.0 / 3.0 * youngs[grain_materials[pair[:, 0]], grain_materials[pair[:, 1]]] \
        * np.sqrt(r_eff) * overlap**1.5
    wall_force = 4.0 / 3.0 * youngs[grain_materials[wall_grain], wall_material[wall_id]] \
        * np.sqrt(radii[wall_grain]) * wall_overlap**1.5
    largest_force = float(max(pair_force.max(initial=0.0), wall_force.max(initial=0.0)))
    converged = bool(np.abs(gradient[variable]).max(initial=0.0) <= force_tolerance * weight)
    if update:
        state.positions[:] = positions
    return Relaxation(positions.copy(), float(before), float(after), np.array(trace),
                      int(result.nit),
                      int(result.nfev), built["count"], converged, str(result.message),
                      overlaps_before,
                      overlap_distribution(positions, radii, walls, lists, symmetry),
                      float(net_norm.max()), over_weight, largest_force)
