"""Insertion and settling: geometry checks and a settled bed against its weight."""
import numpy as np
import pytest

import graindyn as gd
from graindyn.protocols.prepare import (BoxRegion, CylinderRegion, lattice_insertion,
                                        random_insertion, settle)


def _no_overlap(pos, radii):
    d = np.linalg.norm(pos[:, None] - pos[None], axis=-1) + np.eye(len(radii)) * 1e9
    return np.all(d >= radii[:, None] + radii[None] - 1e-15)


def test_random_insertion_box_and_cylinder(rng):
    radii = gd.sample_radii(300, "uniform", rng, d_min=0.85e-3, d_max=1.15e-3)
    pos, r = random_insertion(radii, BoxRegion((0, 0, 0), (10e-3, 10e-3, 20e-3)), rng)
    assert _no_overlap(pos, r)
    assert np.all(pos - r[:, None] >= -1e-15) and np.all(pos[:, 2] + r <= 20e-3 + 1e-15)
    pos, r = random_insertion(radii, CylinderRegion((0, 0), 4e-3, 0, 60e-3), rng)
    assert _no_overlap(pos, r)
    assert np.all(np.hypot(pos[:, 0], pos[:, 1]) + r <= 4e-3 + 1e-15)


def test_random_insertion_too_full_is_refused(rng):
    radii = np.full(500, 0.5e-3)
    with pytest.raises(ValueError, match="too small"):
        random_insertion(radii, BoxRegion((0, 0, 0), (5e-3, 5e-3, 5e-3)), rng)


def test_lattice_insertion_2d(rng):
    radii = np.full(50, 0.5e-3)
    pos, vel = lattice_insertion(radii, BoxRegion((0, 0), (10e-3, 20e-3)), rng, dim=2,
                                 speed=0.1)
    assert _no_overlap(pos, radii) and np.allclose(pos[:, 2], 0) and np.allclose(vel[:, 2], 0)
    assert np.allclose(np.linalg.norm(vel, axis=1), 0.1)


def test_radii_distributions(rng):
    r = gd.sample_radii(20000, "normal", rng, mean=1e-3, std=1e-4, d_min=0.8e-3, d_max=1.2e-3)
    assert abs(2 * r.mean() - 1e-3) < 5e-6 and 2 * r.min() >= 0.8e-3 and 2 * r.max() <= 1.2e-3
    r = gd.sample_radii(20000, "lognormal", rng, mean=1e-3, std=2e-4)
    assert abs(2 * r.mean() - 1e-3) < 1e-5 and abs(np.std(2 * r) - 2e-4) < 1e-5
    with pytest.raises(ValueError, match="d_min <= d_max"):
        gd.sample_radii(10, "uniform", rng, d_min=2e-3, d_max=1e-3)


def test_settled_bed_carries_its_weight(rng):
    """A settled bed in a frictionless-walled box: the floor carries the whole weight
    (no wall friction to hold any of it) and the criterion E_k/E_p <= 1e-6 is reached."""
    side = 6e-3
    radii = gd.sample_radii(150, "uniform", rng, d_min=0.9e-3, d_max=1.1e-3)
    pos, radii = random_insertion(radii, BoxRegion((0, 0, 0), (side, side, 15e-3)), rng)
    st = gd.State.create(pos, radii, 2650.0)
    grain = gd.Material(density=2650.0, youngs_modulus=1e7, poisson_ratio=0.3, restitution=0.5,
                        friction_sliding=0.5, tangential_damping=1.0)
    wall = gd.Material(density=2650.0, youngs_modulus=1e7, poisson_ratio=0.3, restitution=0.5,
                       friction_sliding=0.0)
    sim = gd.Simulation(st, [grain, wall], gd.ContactModel("hertz", "tsuji", "mindlin"),
                        walls=gd.box((0, 0, 0), (side, side, 30e-3), material=1))
    report = settle(sim, max_time=1.0, bottom_wall="zlo", cross_section=side * side)
    assert report["reached"]
    assert report["apparent_weight_ratio"] == pytest.approx(1.0, abs=0.05)
    # the instantaneous floor force still rings with the bed's elastic oscillations;
    # averaged over time it equals the weight (momentum balance)
    floor = sim.walls.index("zlo")
    samples = []
    sim.run(time=0.02, every=[(gd.Periodic(steps=7), lambda s: samples.append(
        s.walls.normal_force(floor)))])
    assert np.mean(samples) / report["total_weight_N"] == pytest.approx(1.0, abs=2e-3)
    assert 0.45 < report["packing_fraction"] < 0.64
    assert 3.0 < report["coordination_number"] < 7.0


def _spinner(tangential, twisting, against_image=False):
    """A grain resting on a held grain, spinning about the line through both, and a
    grain on the floor beside them; no sliding at the spinner's contact (the spin axis
    is its normal), so only a twisting law can stop it.  Straight above the held grain;
    or, ``against_image``, leaning on its own image through the symmetry plane x = 0
    from a held grain half a radius further from the plane (frictionless equilibrium:
    the image pushes it along x, the held grain along their line), where it never
    slides either (the image mirrors its spin)."""
    from graindyn.core.symmetry import Symmetry

    r, young, poisson, density = 1e-3, 1e7, 0.3, 2650.0
    weight = density * 4 / 3 * np.pi * r**3 * 9.81
    # Hertz, F = 4/3 E* sqrt(R* d) d with R* = r/2 for the pair and for the image (whose
    # overlap is twice the grain's penetration of the plane): the overlaps at rest
    stiffness = 4 / 3 * young / (2 * (1 - poisson**2)) * np.sqrt(r / 2)
    x0, x1, d0 = 1.5 * r, r, 0.0
    for _ in range(50):
        sine = (x0 - x1) / (2 * r - d0) if against_image else 0.0
        f0 = weight / np.sqrt(1 - sine**2)
        d0 = (f0 / stiffness) ** (2 / 3)
        x1 = r - 0.5 * (f0 * sine / stiffness) ** (2 / 3) if against_image else x0
    z1 = 2 * r + np.sqrt((2 * r - d0)**2 - (x0 - x1)**2)
    pos = np.array([[x0, 5e-3, 2 * r], [x1, 5e-3, z1], [6e-3, 2e-3, r]])
    st = gd.State.create(pos, np.full(3, r), 2650.0)
    st.fixed[0] = 1
    axis = (pos[1] - pos[0]) / np.linalg.norm(pos[1] - pos[0])
    st.angular_velocities[1] = 100.0 * axis
    grain = gd.Material(density=density, youngs_modulus=young, poisson_ratio=poisson,
                        restitution=0.5, friction_sliding=0.5, tangential_damping=1.0,
                        gamma_nt=2e4)
    model = gd.ContactModel("hertz", "tsuji", tangential, twisting=twisting)
    # the box's side reaches past the plane: only the image touches the grains there
    return gd.Simulation(st, [grain], model, walls=gd.box((-1e-2, 0, 0), (1e-2, 1e-2, 2e-2)),
                         symmetry=[Symmetry("x", 0.0)] if against_image else ())


@pytest.mark.parametrize("against_image", [False, True])
def test_a_settling_held_up_by_a_spinning_grain_says_which_grain(against_image):
    """Without twisting resistance the spinner keeps its rotational energy for ever:
    the criterion is not met, and the report and the settle phase's log line name the
    grain, which slips nowhere.  With Oquendo's viscous twisting law (Eq. 2) the same
    grain stops and the criterion is met.  Against its own image (symmetry plane) the
    same holds: the image contact carries no tangential force."""
    from graindyn.protocols.phases import Settle, SettleSettings

    sim = _spinner("mindlin", "none", against_image)
    spin = 0.5 * sim.state.inertias[1] * 100.0**2
    report = settle(sim, max_time=0.05, bottom_wall="zlo", cross_section=1e-4)
    assert not report["reached"]
    assert report["energy_J"]["rotational"] == pytest.approx(spin, rel=1e-6)
    assert report["rotational_share"] > 0.999
    assert report["energy_ratio"] > 1e-3
    (holder,) = report["kinetic_holders"]
    assert holder["grain"] == 1 and holder["grain_contacts"] == 1
    assert holder["image_contacts"] == (1 if against_image else 0)
    assert holder["slip_m_s"] < 1e-9 * holder["surface_speed_m_s"]
    line = Settle(SettleSettings(max_time=0.05), None).verdict({"report": report})
    assert "grain 1 holds 100 % of it and slips at none of its grain contacts" in line
    assert "contact.twisting" in line

    sim = _spinner("oquendo", "oquendo", against_image)     # test_law_scenarios's laws
    report = settle(sim, max_time=0.05, bottom_wall="zlo", cross_section=1e-4)
    assert report["reached"] and "kinetic_holders" not in report
    assert Settle(SettleSettings(max_time=0.05), None).verdict({"report": report}) is None
