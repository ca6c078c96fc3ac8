"""Relaxation by minimising Karrech's functional (Eq. 29): the nine-grain cell of Fig. 8,
analytic equilibria of two bodies, and the compiled gradient against finite differences."""
import numpy as np
import pytest
from scipy.optimize import brentq

import graindyn as gd
from graindyn.core.symmetry import Symmetry, SymmetryPlanes
from graindyn.core.walls import Cylinder, Plane, Walls
from graindyn.engines.soft.relaxation import candidate_lists, functional, relax, youngs_table

# Karrech Table 1: diorite grains; steel walls
DIORITE = gd.Material("diorite", density=2710.0, youngs_modulus=46.9e9, poisson_ratio=0.25)
STEEL = gd.Material("steel", density=7800.0, youngs_modulus=210e9, poisson_ratio=0.3)
R = 3.2e-3                                       # [m]
G = 9.81


def _hertz_overlap(force, youngs_eff, r_eff):
    """delta [m] with 4/3 E* sqrt(R*) delta^(3/2) = force [N] (Karrech Eq. 5)."""
    return (force / (4.0 / 3.0 * youngs_eff * np.sqrt(r_eff))) ** (2.0 / 3.0)


def _nine_grain_cell():
    """Karrech's cell of nine grains (Fig. 8) in 3D: a body-centred cube of side 2.4 R
    whose eight corner grains are the fixed frontier, loose enough that the central
    grain rests on the four lower ones; the central grain, as an extrapolation might
    leave it, sunk about 0.055 R into them and off centre.  (A flat 3 x 3 cell of
    spheres would not hold its free centre in 3D: it could leave the plane.)"""
    side = 2.4 * R
    corners = np.array([[x, y, z] for x in (-0.5, 0.5) for y in (-0.5, 0.5)
                        for z in (-0.5, 0.5)]) * side
    centre = np.array([0.03 * R, -0.02 * R, -0.5 * side + 0.95 * R])
    state = gd.State.create(np.vstack([corners, centre]), np.full(9, R), 2710.0)
    state.fixed[:8] = 1
    return state, side


def test_nine_grain_cell_relaxes_to_its_equilibrium(one_thread):
    state, side = _nine_grain_cell()
    start = state.positions.copy()
    result = relax(state, [DIORITE])
    assert result.converged, result.message
    # the paper's excessive penetration, relieved to the equilibrium level
    assert result.overlaps_before.max > 0.05
    youngs_eff = DIORITE.youngs_modulus / (2 * (1 - DIORITE.poisson_ratio ** 2))
    weight = state.masses[8] * G

    def imbalance(overlap):                  # 4 contacts carry the weight
        distance = 2 * R - overlap
        height = np.sqrt(distance**2 - side**2 / 2)
        force = 4.0 / 3.0 * youngs_eff * np.sqrt(R / 2) * overlap**1.5
        return 4 * force * height / distance - weight

    expected = brentq(imbalance, 1e-14, 1e-5)
    assert result.overlaps_after.count == 4
    assert result.overlaps_after.max * R == pytest.approx(expected, rel=1e-3)
    assert result.overlaps_after.p50 * R == pytest.approx(expected, rel=1e-3)
    assert result.overlaps_after.largest < 1e-4 * result.overlaps_before.largest
    assert np.abs(result.positions[8, :2]).max() < 1e-4 * R          # centred
    assert result.functional_after < result.functional_before
    trace = result.functional_trace
    assert trace.size == result.iterations + 1 and trace[-1] == pytest.approx(
        result.functional_after, rel=1e-9)
    assert np.all(np.diff(trace) <= 1e-12 * np.abs(trace).max())     # decreasing
    assert np.array_equal(result.positions[:8], start[:8])            # frontier fixed
    assert np.array_equal(state.positions, start)                     # input untouched
    # static equilibrium: net force on the free grain against its weight
    assert result.residual_over_weight < 1e-4
    assert result.residual_force < 1e-4 * result.largest_contact_force
    assert 0 < result.iterations < 500


def test_grain_on_a_fixed_grain_and_on_a_wall(one_thread):
    # a grain of 2.5 mm resting on a fixed one of 3.2 mm: m g = 4/3 E* sqrt(R*) delta^1.5
    small = 2.5e-3
    state = gd.State.create([[0, 0, 0], [0, 0, R + small - 1e-4]], [R, small], 2710.0)
    state.fixed[0] = 1
    result = relax(state, [DIORITE])
    youngs_eff = DIORITE.youngs_modulus / (2 * (1 - DIORITE.poisson_ratio ** 2))
    expected = _hertz_overlap(state.masses[1] * G, youngs_eff, R * small / (R + small))
    overlap = R + small - result.positions[1, 2]
    assert result.converged and overlap == pytest.approx(expected, rel=1e-4)
    assert np.array_equal(result.positions[1, :2], [0.0, 0.0])
    # the same grain on a steel floor: R* = R, E* mixed with the wall's material
    state = gd.State.create([[0, 0, small - 1e-4]], [small], 2710.0)
    floor = Walls([Plane((0, 0, 0), (0, 0, 1), material=1)])
    result = relax(state, [DIORITE, STEEL], walls=floor, update=True)
    youngs_eff = 1 / ((1 - 0.25**2) / 46.9e9 + (1 - 0.3**2) / 210e9)
    expected = _hertz_overlap(state.masses[0] * G, youngs_eff, small)
    assert result.converged
    assert small - result.positions[0, 2] == pytest.approx(expected, rel=1e-4)
    assert np.array_equal(state.positions, result.positions)          # update=True
    # an applied load of nine weights on top: ten weights on the contact
    load = np.array([[0.0, 0.0, -9 * state.masses[0] * G]])
    result = relax(state, [DIORITE, STEEL], walls=floor, loads=load)
    expected = _hertz_overlap(10 * state.masses[0] * G, youngs_eff, small)
    assert small - result.positions[0, 2] == pytest.approx(expected, rel=1e-4)


@pytest.mark.parametrize("excess", ["none", "pairs", "walls"])
@pytest.mark.parametrize("quarter", [False, True])
def test_functional_gradient_against_finite_differences(one_thread, quarter, excess):
    """The gradient of Eq. 29 is its derivative, also with the half potentials of the
    image contacts of two symmetry planes (the quarter of the cylinder: grains near
    x = 0 and y = 0, each touching its own images and the others'), and with only the
    overlaps beyond those of an allowed configuration entering (excess: of the grain
    pairs, or of the grain-wall contacts too, against walls placed elsewhere)."""
    rng = np.random.default_rng(7)
    n = 12
    low = [0.5e-3, 0.5e-3, 2.6e-3] if quarter else [-4e-3, -4e-3, 2.6e-3]
    positions = rng.uniform(low, [4e-3, 4e-3, 12e-3], (n, 3))
    radii = rng.uniform(2.6e-3, 3.8e-3, n)
    state = gd.State.create(positions, radii, 2710.0, materials=rng.integers(0, 2, n))
    walls = Walls([Plane((0, 0, 0), (0, 0, 1), material=1),
                   Cylinder((0, 0, 0), (0, 0, 1), 7e-3, material=1)])
    planes = SymmetryPlanes([Symmetry("x"), Symmetry("y")] if quarter else [])
    youngs = youngs_table([DIORITE, STEEL])
    lists = candidate_lists(state.positions, radii, 10e-3, walls, planes)
    assert (lists.image_codes.size > 20) == quarter
    loads = rng.normal(0, 0.1, (n, 3))
    anchor = rng.uniform(0.0, 1e3, n)            # [N/m], the springs to the reference
    free = np.ones(n, np.int8)
    gravity = np.array([0.0, 0.0, -G])
    reference = state.positions + rng.normal(0, 1e-4, (n, 3))
    allowed = state.positions + rng.normal(0, 3e-4, (n, 3))
    allowed_offset = walls.offset + rng.normal(0, 3e-4, walls.offset.shape)

    def energy(at):
        gradient = np.zeros((n, 3))
        value = functional(at, reference, radii, state.masses, state.materials.astype(np.int64),
                           youngs, gravity, loads, anchor, free, lists.start,
                           lists.partners,
                           walls.periodic_flag, walls.periodic_length, lists.wall_start,
                           lists.wall_ids, walls.kind, walls.geometry, walls.offset,
                           walls.material.astype(np.int64), lists.image_start,
                           lists.image_codes, planes.at, allowed, excess != "none",
                           allowed_offset, excess == "walls", gradient)
        return value, gradient

    value, gradient = energy(state.positions)
    assert value > 0 and np.abs(gradient).max() > 1.0          # contacts are loaded
    step = 1e-9
    numeric = np.zeros((n, 3))
    for b in range(n):
        for d in range(3):
            plus, minus = state.positions.copy(), state.positions.copy()
            plus[b, d] += step
            minus[b, d] -= step
            numeric[b, d] = (energy(plus)[0] - energy(minus)[0]) / (2 * step)
    assert np.allclose(gradient, numeric, rtol=1e-5, atol=1e-6 * np.abs(gradient).max())
    free[:3] = 0
    assert np.all(energy(state.positions)[1][:3] == 0.0)


def test_lists_are_rebuilt_when_grains_move_far(one_thread):
    """A column of grains overlapping by 0.3 R spreads over several skins."""
    z = np.arange(6) * 1.7 * R + R
    state = gd.State.create(np.stack([np.zeros(6), np.zeros(6), z], 1), np.full(6, R),
                            2710.0)
    floor = Walls([Plane((0, 0, 0), (0, 0, 1))])
    result = relax(state, [DIORITE], walls=floor, skin=0.05 * R)
    assert result.rebuilds > 1 and result.converged
    assert result.overlaps_after.max < 1e-4
    assert result.residual_over_weight < 1e-3


def test_relaxation_without_gravity_only_removes_the_overlaps(one_thread):
    """Simulation.relax(gravity=False, anchor=1): a grain pushed 0.2 R into a fixed
    grain resting on the floor comes out of it until the contact force equals the
    anchor's spring, one weight per mean radius of displacement (a small overlap),
    where the Eq. 29 relaxation with gravity stops at the Hertz overlap that carries
    its weight; the fixed grain stays."""
    r = 3e-3
    walls = [Plane((0, 0, 0), (0, 0, 1), material=1)]
    sims = []
    for _ in range(2):
        state = gd.State.create([[0.0, 0.0, r], [0.0, 0.0, 2.8 * r]], [r, r], 2710.0)
        state.fixed[0] = 1
        sims.append(gd.Simulation(state, [DIORITE, STEEL], walls=walls))
    loose = sims[0].relax(gravity=False, anchor=1.0, force_tolerance=1e-8)
    loaded = sims[1].relax(force_tolerance=1e-8)
    youngs_eff = 1.0 / (2 * (1 - 0.25**2) / 46.9e9)
    weight = sims[1].state.masses[1] * G
    overlap = [2 * r - (s.state.positions[1, 2] - s.state.positions[0, 2]) for s in sims]
    assert loose.converged and loaded.converged
    moved = sims[0].state.positions[1, 2] - 2.8 * r
    hertz = 4.0 / 3.0 * youngs_eff * np.sqrt(r / 2) * overlap[0] ** 1.5
    assert 0.0 < overlap[0] < 1e-3 * r
    assert hertz == pytest.approx(weight / r * moved, rel=1e-5)       # spring = contact
    assert overlap[1] == pytest.approx(_hertz_overlap(weight, youngs_eff, r / 2), rel=1e-4)
    assert sims[0].state.positions[0, 2] == r and sims[1].state.positions[0, 2] == r


def test_a_relaxation_keeps_the_contact_history_when_asked(one_thread):
    """Simulation.relax(start=, keep_contacts=True): a grain sheared on a fixed one
    (Mindlin's tangential spring loaded), moved into it as an extrapolation would and
    relaxed without gravity, still touches it and keeps its spring, which the next
    step caps at mu f_n of the relaxed, lightly loaded contact (Coulomb); without
    keep_contacts the spring is forgotten (relocation).  Both relax to the same
    positions."""
    r = 3e-3
    rock = gd.Material("rock", density=2710.0, youngs_modulus=46.9e9, poisson_ratio=0.25,
                       friction_sliding=0.5)
    model = gd.ContactModel(normal="hertz", tangential="mindlin")
    sims = []
    for _ in range(2):
        state = gd.State.create([[0.0, 0.0, 0.0], [0.0, 0.0, 1.9999 * r]], [r, r], 2710.0)
        state.fixed[0] = 1
        state.velocities[1] = (1e-3, 0.0, 0.0)
        sim = gd.Simulation(state, [rock], model, gravity=(0.0, 0.0, 0.0))
        sim.run(steps=20)
        sims.append(sim)
    spring = sims[0].pairs.history[0].copy()
    assert abs(spring[0]) > 0.0
    start = sims[0].state.positions.copy()
    start[1, 2] -= 0.05 * r
    kept = sims[0].relax(gravity=False, anchor=1.0, start=start, keep_contacts=True)
    lost = sims[1].relax(gravity=False, anchor=1.0, start=start)
    np.testing.assert_array_equal(kept.positions, lost.positions)
    assert kept.overlaps_after.count == 1
    for sim in sims:
        sim.run(steps=1)
    contact = sims[0].contacts()
    shear = np.linalg.norm(contact.tangential_force[0])
    assert shear == pytest.approx(0.5 * np.linalg.norm(contact.normal_force[0]), rel=2e-3)
    kept_spring = sims[0].pairs.history[0, 0]
    assert np.sign(kept_spring) == np.sign(spring[0]) and abs(kept_spring) < abs(spring[0])
    assert np.abs(sims[1].pairs.history[0, :3]).max() < 1e-12 * abs(spring[0])
    lost = sims[1].contacts()
    assert np.linalg.norm(lost.tangential_force[0]) < 1e-12 * lost.normal_force[0]


def test_only_the_excess_overlap_is_relaxed(one_thread):
    """relax(allowed=): a grain resting on a fixed grain with the overlap of its
    weight, then pushed 0.05 R further into it (as an extrapolation might), relaxed
    without gravity: with the resting configuration allowed it comes back to that
    overlap (the contact stays loaded, within the anchor's pull), where the plain
    overlaps relaxation empties the contact."""
    r = 3e-3
    youngs_eff = 1.0 / (2 * (1 - 0.25**2) / 46.9e9)
    state = gd.State.create([[0.0, 0.0, 0.0], [0.0, 0.0, 2 * r]], [r, r], 2710.0)
    weight = state.masses[1] * G
    resting = 2 * r - _hertz_overlap(weight, youngs_eff, r / 2)
    state.positions[1, 2] = resting
    state.fixed[0] = 1
    allowed = state.positions.copy()
    state.positions[1, 2] -= 0.05 * r
    kept = relax(state, [DIORITE], gravity=(0, 0, 0), anchor=1.0, allowed=allowed,
                 force_tolerance=1e-9)
    emptied = relax(state, [DIORITE], gravity=(0, 0, 0), anchor=1.0, force_tolerance=1e-9)
    assert kept.converged and emptied.converged
    rest_overlap = 2 * r - resting
    start = state.positions[1, 2]
    for result, keeps in ((kept, rest_overlap), (emptied, 0.0)):
        height = result.positions[1, 2]
        anchor_force = weight / r * (height - start)          # one weight per radius
        excess = 2 * r - height - keeps
        assert excess == pytest.approx(_hertz_overlap(anchor_force, youngs_eff, r / 2),
                                       rel=1e-3)
    assert 2 * r - kept.positions[1, 2] > rest_overlap          # still loaded
    assert 2 * r - emptied.positions[1, 2] < 0.2 * rest_overlap  # emptied
    np.testing.assert_array_equal(kept.positions[0], allowed[0])
    with pytest.raises(ValueError, match="allowed must be the"):
        relax(state, [DIORITE], allowed=allowed[:1])


def test_grain_wall_contacts_keep_their_allowed_overlap(one_thread):
    """relax(allowed=, allowed_walls=): a grain resting on a steel floor with the
    overlap of its weight, pushed 0.05 R further into it, relaxed without gravity:
    with the walls' offsets of the resting configuration given, the contact keeps that
    overlap (within the anchor's pull), where without them it is emptied; and a grain
    moved on together with the floor (the whole translated) is left where it is, its
    overlap being the allowed one against the floor where it was."""
    r = 3e-3
    youngs_eff = 1 / ((1 - 0.25**2) / 46.9e9 + (1 - 0.3**2) / 210e9)
    state = gd.State.create([[0.0, 0.0, r]], [r], 2710.0)
    weight = state.masses[0] * G
    rest_overlap = _hertz_overlap(weight, youngs_eff, r)
    state.positions[0, 2] = r - rest_overlap
    floor = Walls([Plane((0, 0, 0), (0, 0, 1), material=1)])
    allowed, offsets = state.positions.copy(), floor.offset.copy()
    state.positions[0, 2] -= 0.05 * r
    start = state.positions[0, 2]
    kept = relax(state, [DIORITE, STEEL], walls=floor, gravity=(0, 0, 0), anchor=1.0,
                 allowed=allowed, allowed_walls=offsets, force_tolerance=1e-7)
    emptied = relax(state, [DIORITE, STEEL], walls=floor, gravity=(0, 0, 0), anchor=1.0,
                    allowed=allowed, force_tolerance=1e-7)
    assert kept.converged and emptied.converged
    for result, keeps in ((kept, rest_overlap), (emptied, 0.0)):
        height = result.positions[0, 2]
        anchor_force = weight / r * (height - start)          # one weight per radius
        assert r - height - keeps == pytest.approx(
            _hertz_overlap(anchor_force, youngs_eff, r), rel=1e-3)
    assert r - kept.positions[0, 2] > rest_overlap              # still loaded
    assert r - emptied.positions[0, 2] < 0.2 * rest_overlap     # emptied
    shift = np.array([0.0, 0.0, -0.05 * r])
    floor.place(0, offsets[0] + shift)
    state.positions[:] = allowed + shift
    moved = relax(state, [DIORITE, STEEL], walls=floor, gravity=(0, 0, 0), anchor=1.0,
                  allowed=allowed, allowed_walls=offsets)
    assert moved.functional_before == 0.0 and moved.iterations == 0
    np.testing.assert_array_equal(moved.positions, allowed + shift)
    with pytest.raises(ValueError, match="allowed_walls needs allowed"):
        relax(state, [DIORITE, STEEL], walls=floor, allowed_walls=offsets)
    with pytest.raises(ValueError, match="allowed_walls must be the"):
        relax(state, [DIORITE, STEEL], walls=floor, allowed=allowed,
              allowed_walls=offsets[:, :2])
