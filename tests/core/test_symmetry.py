"""Symmetry planes (core/symmetry.py, engines/soft/image_contacts.py) against the full
symmetric system they stand for: the grains of the kept part must move as the same
grains of the full system, whose other part is their mirror image, started
symmetric.  A grain and its own image; a pair whose contact straddles a plane; a
corner grain and its double image; energies half those of the full system."""
import math

import numpy as np
import pytest

import graindyn as gd
from graindyn.core.symmetry import Symmetry, SymmetryPlanes

R = 1e-3                    # grain radius [m]
DENSITY = 2500.0            # [kg/m^3]

pytestmark = pytest.mark.usefixtures("one_thread")


def _system(positions, velocities, spins, symmetry=(), gravity=(0.0, 0.0, 0.0), walls=(),
            friction=0.5, radii=None, **options):
    """Damped frictional Hertz-Mindlin grains (E = 1e7 Pa) with the given state."""
    positions = np.asarray(positions, float)
    radii = np.full(len(positions), R) if radii is None else np.asarray(radii, float)
    state = gd.State.create(positions, radii, DENSITY, velocities=np.asarray(velocities, float))
    state.angular_velocities[:] = spins
    material = gd.Material(youngs_modulus=1e7, poisson_ratio=0.3, restitution=0.6,
                           friction_sliding=friction, friction_static=friction)
    return gd.Simulation(state, [material], gd.ContactModel("hertz", "tsuji", "mindlin"),
                         walls=list(walls), gravity=gravity, dt=2e-7, symmetry=symmetry,
                         **options)


def _mirrored(planes, positions, velocities, spins):
    """The full system: the grains and their images through every mask of ``planes``
    (mask 0 first: the kept grains keep their indices)."""
    sym = SymmetryPlanes(planes)
    n = len(positions)
    out = [np.asarray(positions, float), np.asarray(velocities, float),
           np.asarray(spins, float)]
    full = [list(a) for a in out]
    for mask in sym.masks():
        sign = np.array([-1.0 if mask >> d & 1 else 1.0 for d in range(3)])
        full[0] += list(sym.image(out[0], np.full(n, mask)))
        full[1] += list(out[1] * sign)
        full[2] += list(out[2] * sign * np.prod(sign))
    return [np.array(a) for a in full]


def _compare(planes, positions, velocities, spins, steps, **setting):
    """Run the kept part with ``planes`` and the full system; returns both."""
    kept = _system(positions, velocities, spins, symmetry=planes, **setting)
    full = _system(*_mirrored(planes, positions, velocities, spins), **setting)
    for s in (kept, full):
        s.run(steps=steps)
    return kept, full


def _assert_same_motion(kept, full, n):
    scale = {"positions": 1e-12, "velocities": 1e-9, "angular_velocities": 1e-6}
    for name, tol in scale.items():
        np.testing.assert_allclose(getattr(kept.state, name), getattr(full.state, name)[:n],
                                   rtol=0, atol=tol, err_msg=name)


def test_grain_meets_its_own_image_as_the_mirror_grain_of_the_full_pair():
    """A grain thrown at the plane x = 0 bounces off its image: the normal force of two
    grains (Hertz with R* = R/2, overlap twice its penetration), and no tangential force
    (by symmetry): the full pair gives the same motion, half the energies."""
    planes = [Symmetry("x", 0.0)]
    kept, full = _compare(planes, [[1.05 * R, 0.0, 0.0]], [[-0.3, 0.1, 0.05]],
                          [[5.0, 3.0, -2.0]], 12000)
    assert kept.collisions == 1
    assert kept.state.velocities[0, 0] > 0           # it came back
    _assert_same_motion(kept, full, 1)
    e_kept, e_full = kept.energies(), full.energies()
    for name in ("kinetic", "rotational", "dissipated_normal"):
        assert e_kept[name] == pytest.approx(0.5 * e_full[name], rel=1e-9), name


def test_image_contact_in_the_middle_of_the_bounce_has_the_pair_force():
    """Halfway through the bounce the grain's force is the Hertz force of the pair with
    its image, whose overlap is twice the grain's penetration of the plane."""
    sim = _system([[0.99 * R, 0.0, 0.0]], [[0.0, 0.0, 0.0]], [[0.0, 0.0, 0.0]],
                  symmetry=[Symmetry("x", 0.0)])
    sim.run(steps=1)
    contacts = sim.image_contacts()
    assert contacts.grain.tolist() == [0] and contacts.image_of.tolist() == [0]
    overlap = 2 * R - 2 * sim.state.positions[0, 0]
    e_star = 1e7 / (2 * (1 - 0.3**2))
    hertz = 4.0 / 3.0 * e_star * math.sqrt(R / 2) * overlap**1.5
    assert contacts.normal_force[0] == pytest.approx(hertz, rel=1e-3)
    np.testing.assert_allclose(contacts.normal[0], [1.0, 0.0, 0.0])


def test_pair_near_a_plane_slides_as_in_the_full_system():
    """Two grains near the plane x = 0 that collide with friction and spin, then with
    their images: the images of the full system's mirror half, with their contact
    histories, give the same motion to rounding."""
    rng = np.random.default_rng(3)
    positions = [[1.1 * R, 0.0, 0.0], [1.3 * R, 2.05 * R, 0.2 * R]]
    velocities = [[-0.2, 0.15, 0.0], [-0.25, -0.2, 0.05]]
    spins = rng.normal(0.0, 50.0, (2, 3))
    kept, full = _compare([Symmetry("x", 0.0)], positions, velocities, spins, 8000)
    assert kept.collisions >= 3 and kept.dissipated["tangential"] > 0
    _assert_same_motion(kept, full, 2)
    assert kept.energies()["dissipated_tangential"] == pytest.approx(
        0.5 * full.energies()["dissipated_tangential"], rel=1e-6)


@pytest.mark.parametrize("dim", [2, 3])
def test_cluster_pressed_into_the_corner_feels_the_forces_of_the_full_system(dim):
    """Grains of several sizes pressed deep into the corner of two planes (x = 0, y = 0),
    deep enough that each touches the images of the others (a contact straddling a
    plane between two different grains), through one plane and through both: forces,
    torques and motion over a few hundred steps, and the elastic energy, as those of
    the same grains in the full system of four mirror copies."""
    rng = np.random.default_rng(11)
    n = 6
    radii = R * rng.uniform(0.9, 1.4, n)
    grid = np.array([(x, y, 0.0) for x in range(3) for y in range(2)], float)
    positions = R * (0.6 + 1.5 * grid + rng.uniform(-0.05, 0.05, (n, 3)))
    if dim == 2:
        positions[:, 2] = 0.0
    velocities = rng.normal(0.0, 0.05, (n, 3))
    spins = rng.normal(0.0, 30.0, (n, 3))
    if dim == 2:
        velocities[:, 2] = 0.0
        spins[:, :2] = 0.0
    planes = [Symmetry("x", 0.0), Symmetry("y", 0.0)]
    full = _mirrored(planes, positions, velocities, spins)

    def build(arrays, symmetry):
        state = gd.State.create(arrays[0], np.resize(radii, len(arrays[0])), DENSITY,
                                dim=dim, velocities=arrays[1])
        state.angular_velocities[:] = arrays[2]
        material = gd.Material(youngs_modulus=1e7, poisson_ratio=0.3, restitution=0.6,
                               friction_sliding=0.5, friction_static=0.5)
        return gd.Simulation(state, [material], gd.ContactModel("hertz", "tsuji", "mindlin"),
                             gravity=(0.0, 0.0, 0.0), dt=2e-8, overlap_limit=2.0,
                             symmetry=symmetry)
    kept, whole = build([positions, velocities, spins], planes), build(full, ())
    for s in (kept, whole):
        s.run(steps=1)
    cross = kept.image_contacts()
    assert np.any(cross.image_of != cross.grain)                 # straddling pairs
    assert {1, 2, 3} <= set(cross.mask.tolist())                 # x, y and both
    for s in (kept, whole):
        s.run(steps=300)
    scale = np.abs(whole.state.forces).max()
    np.testing.assert_allclose(kept.state.forces, whole.state.forces[:n], rtol=0,
                               atol=1e-9 * scale)
    np.testing.assert_allclose(kept.state.torques, whole.state.torques[:n], rtol=0,
                               atol=1e-9 * scale * R)
    np.testing.assert_allclose(kept.state.positions, whole.state.positions[:n], rtol=0,
                               atol=1e-12)
    assert kept.energies()["elastic"] == pytest.approx(0.25 * whole.energies()["elastic"],
                                                       rel=1e-9)


def test_corner_grain_meets_its_double_image_in_the_quarter_model():
    """A grain in the corner of the planes x = 0 and y = 0 (3D) or a disk in 2D meets
    its images through each plane and through both: the full system of four grains."""
    planes = [Symmetry("x", 0.0), Symmetry("y", 0.0)]
    kept, full = _compare(planes, [[1.02 * R, 1.2 * R, 0.0]], [[-0.2, -0.3, 0.1]],
                          [[10.0, -20.0, 30.0]], 10000)
    _assert_same_motion(kept, full, 1)
    assert kept.collisions >= 2


def test_disk_in_2d_against_the_plane_y_axis():
    """2D: disks below the plane y = 1 mm (side -1), as the four disks of the full
    system."""
    planes = [Symmetry("y", 1e-3, side=-1)]
    positions = np.array([[0.0, 1e-3 - 1.05 * R, 0.0], [2.1 * R, 1e-3 - 1.3 * R, 0.0]])
    state = gd.State.create(positions, [R, R], DENSITY, dim=2,
                            velocities=[[0.02, 0.05, 0.0], [-0.02, 0.04, 0.0]])
    full_positions = np.vstack([positions, SymmetryPlanes(planes, 2).image(positions, 2)])
    full_state = gd.State.create(full_positions, [R] * 4, DENSITY, dim=2,
                                 velocities=[[0.02, 0.05, 0.0], [-0.02, 0.04, 0.0],
                                             [0.02, -0.05, 0.0], [-0.02, -0.04, 0.0]])
    material = gd.Material(youngs_modulus=1e7, poisson_ratio=0.3, restitution=0.6,
                           friction_sliding=0.5, friction_static=0.5)
    model = gd.ContactModel("hertz", "tsuji", "mindlin")
    sims = [gd.Simulation(s, [material], model, gravity=(0.0, 0.0, 0.0), dt=2e-7, **o)
            for s, o in ((state, {"symmetry": planes}), (full_state, {}))]
    for s in sims:
        s.run(steps=20000)
    kept, full = sims
    assert kept.collisions >= 2
    _assert_same_motion(kept, full, 2)


def test_symmetry_planes_refuse_what_they_cannot_be():
    with pytest.raises(ValueError, match="at most one per axis"):
        SymmetryPlanes([Symmetry("x", 0.0), Symmetry(0, 1.0)])
    with pytest.raises(ValueError, match="periodic"):
        SymmetryPlanes([Symmetry("x", 0.0)], periodic_flag=(1, 0, 0))
    with pytest.raises(ValueError, match="2D system"):
        SymmetryPlanes([Symmetry("z", 0.0)], dim=2)
    with pytest.raises(ValueError, match="axis must be"):
        SymmetryPlanes([Symmetry("w", 0.0)])


def test_run_restored_from_a_snapshot_goes_on_to_the_bit():
    """The image candidates and their histories are part of a snapshot: a run stopped
    while a grain leans on its image and restored into a fresh Simulation goes on as
    the uninterrupted one."""
    setting = dict(symmetry=[Symmetry("x", 0.0)], gravity=(-9.81, 0.0, -9.81),
                   walls=[gd.Plane((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), name="floor")])
    start = ([[0.999 * R, 0.0, R], [1.2 * R, 0.0, 3.1 * R]], [[0.0, 0.0, 0.0]] * 2,
             [[0.0, 0.0, 0.0]] * 2)
    sim = _system(*start, **setting)
    sim.run(steps=3000)
    assert "images/history" in sim.snapshot()
    saved = sim.snapshot()
    sim.run(steps=2000)
    again = _system(*start, **setting)
    again.restore(saved)
    again.run(steps=2000)
    assert again.image_contacts().grain.size > 0
    for name in ("positions", "velocities", "angular_velocities"):
        np.testing.assert_array_equal(getattr(again.state, name), getattr(sim.state, name))


def test_gpu_backend_refuses_symmetry_planes():
    with pytest.raises(ValueError, match="CPU backend only|backend 'gpu'"):
        _system([[R, 0.0, 0.0]], [[0.0, 0.0, 0.0]], [[0.0, 0.0, 0.0]],
                symmetry=[Symmetry("x", 0.0)], backend="gpu")


def test_relaxation_holds_a_grain_on_its_image_at_the_hertz_equilibrium():
    """Eq. 29 with a symmetry plane: a grain pushed by gravity into the plane x = 0 from
    deep inside its image relaxes to where the Hertz force of the pair (R* = R/2,
    overlap 2 (R - x)) carries its weight; a grain near the plane but above another
    relaxes onto it as in the full system (forces in static equilibrium)."""
    from graindyn.engines.soft.relaxation import relax

    planes = [Symmetry("x", 0.0)]
    state = gd.State.create([[0.7 * R, 0.0, 0.0]], [R], DENSITY)
    material = gd.Material(youngs_modulus=1e7, poisson_ratio=0.3)
    g = 9.81
    result = relax(state, [material], gravity=(-g, 0.0, 0.0), symmetry=planes,
                   force_tolerance=1e-8)
    assert result.converged
    e_star = 1e7 / (2 * (1 - 0.3**2))
    weight = state.masses[0] * g
    overlap = (weight / (4.0 / 3.0 * e_star * math.sqrt(R / 2))) ** (2.0 / 3.0)
    assert 2 * (R - result.positions[0, 0]) == pytest.approx(overlap, rel=1e-5)
    assert result.overlaps_before.max == pytest.approx(0.6, rel=1e-9)   # 2 (R - 0.7 R) / R
    assert result.functional_after < result.functional_before

