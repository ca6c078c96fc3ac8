"""The quarter model (walls.symmetry): a cylinder cut by the symmetry planes x = 0 and
y = 0 through its axis.  The vessel and the insertion are the quarter's; a settled
quarter bed and the full bed made of it and its three mirror images, run on side by
side, carry the same stress on the bottom with the same coordination; configs that
cannot have symmetry planes are refused."""
import copy

import numpy as np
import pytest

import graindyn as gd
from graindyn.analysis.packing import coordination_number
from graindyn.config import ConfigError, build, validate
from graindyn.core.symmetry import SymmetryPlanes
from graindyn.core.triggers import EnergyRatioBelow
from graindyn.protocols import Vessel
from graindyn.protocols.prepare import settle

RADIUS = 6e-3
QUARTER = {
    "run": {"name": "quarter", "seed": 2},
    "grains": {"count": 200, "material": "sand",
               "diameter": {"min": 0.85e-3, "max": 1.15e-3}},
    "materials": [{"name": "sand", "youngs_modulus": 1e7, "poisson_ratio": 0.25,
                   "restitution": 0.3, "friction_sliding": 0.4, "tangential_damping": 1.0}],
    "contact": {"normal": "hertz", "damping": "tsuji", "tangential": "mindlin"},
    "walls": {"material": "sand",
              "container": {"kind": "cylinder", "radius": RADIUS, "height": 40e-3},
              "symmetry": [{"axis": "x"}, {"axis": "y"}]},
    "protocol": {"kind": "deposition", "packing_fraction": 0.1, "threshold": 1e-5,
                 "max_time": 1.0},
}

pytestmark = pytest.mark.usefixtures("one_thread")


def test_the_quarter_vessel_is_a_quarter_of_the_cylinder():
    whole = Vessel.cylinder((1e-3, 2e-3), RADIUS, 0.04)
    planes = [gd.Symmetry("x", 1e-3), gd.Symmetry("y", 2e-3, side=-1)]
    part = whole.mirrored(planes)
    assert part.cross_section == pytest.approx(whole.cross_section / 4)
    assert part.perimeter == pytest.approx(whole.perimeter / 4)
    assert part.lo[:2] == (1e-3, 2e-3 - RADIUS) and part.hi[:2] == (1e-3 + RADIUS, 2e-3)
    region = part.region(0.01)
    lo, hi, _ = region.bounds(3)
    assert region.volume(3) == pytest.approx(part.cross_section * 0.01)
    with pytest.raises(ValueError, match="through its axis"):
        whole.mirrored([gd.Symmetry("x", 0.0)])
    with pytest.raises(ValueError, match="horizontal axis"):
        whole.mirrored([gd.Symmetry("z", 0.0)])
    box = Vessel.box((0.0, 0.0), (0.02, 0.01), True, 2).mirrored([gd.Symmetry("x", 0.01)])
    assert box.cross_section == pytest.approx(0.01) and box.perimeter == pytest.approx(1.0)


def test_configs_that_cannot_have_symmetry_planes_are_refused():
    bad = copy.deepcopy(QUARTER)
    bad["walls"]["symmetry"] = [{"axis": "x", "at": 1e-3}]
    with pytest.raises(ConfigError, match="through its axis"):
        validate(bad)
    bad["walls"]["symmetry"] = [{"axis": "x"}, {"axis": "x"}]
    with pytest.raises(ConfigError, match="at most one per axis"):
        validate(bad)
    hard = copy.deepcopy(QUARTER)
    hard["engine"] = {"kind": "event_driven"}
    with pytest.raises(ConfigError, match="no symmetry planes"):
        validate(hard)


@pytest.fixture(scope="module")
def quarter_bed():
    """The quarter bed of QUARTER settled (E_kin/E_pot <= 1e-5), and its config."""
    config = validate(QUARTER)
    protocol = build.protocol(config)
    state = build.sample(config, protocol, np.random.default_rng(config.run.seed))
    engine = build.engine(config, state, protocol)
    report = settle(engine, EnergyRatioBelow(1e-5), max_time=1.0, bottom_wall="bottom",
                    cross_section=protocol.vessel.cross_section)
    assert report["reached"]
    return config, protocol, engine


def test_the_quarter_is_filled_and_settles_on_its_own_side(quarter_bed):
    config, protocol, engine = quarter_bed
    s = engine.state
    assert s.n == 200
    assert np.all(s.positions[:, :2] > 0.9 * s.radii[:, None])       # on the grains' side
    assert np.all(np.hypot(s.positions[:, 0], s.positions[:, 1]) < RADIUS)
    touching = engine.image_contacts()
    assert touching.grain.size > 10 and set(touching.mask.tolist()) <= {1, 2, 3}


def test_quarter_and_full_bed_carry_the_same_bottom_stress_and_coordination(quarter_bed):
    """The settled quarter and the full cylinder made of it and its three mirror images
    (contact histories started afresh in both), settled on side by side for 0.05 s:
    the stress on the bottom (against the weight of the grains each holds) and the
    coordination number agree within 1 %, the differences the full system's rounding
    lets grow from its exactly symmetric start."""
    config, protocol, engine = quarter_bed
    s = engine.state
    planes = SymmetryPlanes(build.symmetry(config))
    parts = [s.positions] + [planes.image(s.positions, m) for m in planes.masks()]
    full_state = gd.State.create(np.vstack(parts), np.tile(s.radii, 4),
                                 config.materials[0].density)
    whole = build.engine(config.model_copy(update={"walls": config.walls.model_copy(
        update={"symmetry": []})}), full_state, None)
    quarter = build.engine(config, gd.State.create(s.positions.copy(), s.radii.copy(),
                                                   config.materials[0].density), None)
    results = []
    for sim, area in ((quarter, protocol.vessel.cross_section),
                      (whole, 4 * protocol.vessel.cross_section)):
        sim.run(time=0.05)
        weight = float(np.sum(sim.state.masses)) * 9.81
        bottom = sim.walls.normal_force(sim.walls.index("bottom"))
        results.append((bottom / weight, coordination_number(sim), bottom / area))
    (ratio_q, z_q, sigma_q), (ratio_f, z_f, sigma_f) = results
    assert ratio_q == pytest.approx(1.0, abs=0.1)        # a shallow bed: no Janssen arch
    assert ratio_q == pytest.approx(ratio_f, rel=0.01)
    assert sigma_q == pytest.approx(sigma_f, rel=0.01)
    assert z_q == pytest.approx(z_f, rel=0.01)


def test_quarter_deposition_reports_its_settling_history(tmp_path):
    """Karrech et al.'s Fig. 3 for the quarter bed run through the runner: the bottom
    force over the weight, the coordination and the packing fraction against time, the
    last row the settled bed's report (the packing fraction from the floor to the
    highest grain over the quarter's cross-section)."""
    from graindyn.runner import execute

    data = copy.deepcopy(QUARTER)
    data["output"] = {"series_every": 0.01, "figures": True}
    results = execute(validate(data), tmp_path / "run", show_progress=False,
                      echo=lambda *a: None)
    history = results["history"]
    times = [r["time_s"] for r in history]
    assert len(history) > 10 and times == sorted(times)
    last = history[-1]
    assert last["time_s"] == pytest.approx(results["time_s"])
    assert last["coordination"] == pytest.approx(results["coordination_number"])
    assert last["apparent_weight_ratio"] == pytest.approx(results["apparent_weight_ratio"])
    assert last["packing_fraction"] == pytest.approx(results["packing_fraction"])
    assert history[0]["packing_fraction"] < 0.2 < last["packing_fraction"]   # a cloud, then a bed
    assert (tmp_path / "run" / "figures" / "deposition.png").stat().st_size > 10_000
