"""The partially confined mode of the cyclic protocol (protocols/cyclic.py, Karrech et
al. Sec. 5.3): a plate over a fraction of the container's width (a disk in a cylinder,
a rectangle in a 3D box, a segment in 2D), seated on the grains under it, carrying the
haversine on its own area while the grains beside it are a free surface."""
import copy
import math

import numpy as np
import pytest

import graindyn as gd
from graindyn.config import ConfigError, build, validate
from graindyn.core.walls import DISK, PLANE, Disk, Plane, Segment
from graindyn.output import checkpoint
from graindyn.output.rundir import Series
from graindyn.protocols.base import Vessel
from graindyn.protocols.cyclic import load_residuals, plate_area, plate_wall, seat_plate
from graindyn.runner import execute

RADIUS = 4.5e-3
FRACTION = 0.6
AMPLITUDE = 2e3
PARTIAL = {
    "run": {"name": "partial_cyclic", "seed": 3},
    "grains": {"count": 300, "material": "sand",
               "diameter": {"min": 0.85e-3, "max": 1.15e-3}},
    "materials": [{"name": "sand", "youngs_modulus": 1e8, "poisson_ratio": 0.25,
                   "restitution": 0.5, "friction_sliding": 0.4, "tangential_damping": 1.0}],
    "contact": {"normal": "hertz", "damping": "tsuji", "tangential": "mindlin"},
    "walls": {"material": "sand",
              "container": {"kind": "cylinder", "radius": RADIUS, "height": 12e-3}},
    "protocol": {"kind": "cyclic", "packing_fraction": 0.05, "threshold": 1e-5,
                 "max_time": 0.3, "stress_amplitude": AMPLITUDE, "frequency": 50.0,
                 "cycles": 3, "plate_fraction": FRACTION},
    "output": {"series_every": 2e-4, "figures": False},
}


def test_the_plate_is_the_fraction_of_the_width_and_its_area_its_own():
    """Cylinder of radius R: a disk of radius f R, area pi (f R)^2; 3D box of sides
    L_x, L_y: the centred rectangle f L_x by f L_y; 2D: the centred segment f L_x; and
    f = 1 the plane over the whole cross-section, as the fully confined mode has it."""
    cylinder = Vessel.cylinder((1e-3, -2e-3), 5e-3, 1e-2)
    disk = plate_wall(0.8, cylinder, 2, height=7e-3)
    assert isinstance(disk, Disk) and disk.name == "plate" and disk.material == 2
    assert disk.radius == pytest.approx(4e-3) and disk.center == pytest.approx((1e-3, -2e-3, 7e-3))
    assert disk.area == pytest.approx(math.pi * 4e-3**2) == plate_area(0.8, cylinder)
    assert plate_area(0.8, cylinder) == pytest.approx(0.64 * cylinder.cross_section)
    box = Vessel.box((0.0, 0.0, 0.0), (4e-3, 2e-3, 1e-2), True, 3)
    rect = plate_wall(0.5, box, 0, height=3e-3)
    assert isinstance(rect, Segment)
    assert rect.start == pytest.approx((1e-3, 0.5e-3, 3e-3))
    assert rect.end == pytest.approx((3e-3, 0.5e-3, 3e-3))
    assert rect.edge == pytest.approx((0.0, 1e-3, 0.0))
    assert rect.area == pytest.approx(2e-6) == plate_area(0.5, box)
    flat = Vessel.box((0.0, 0.0), (4e-3, 1e-2), True, 2)
    seg = plate_wall(0.75, flat, 0, height=3e-3)
    assert isinstance(seg, Segment) and not np.any(seg.edge)
    assert seg.start == pytest.approx((0.5e-3, 3e-3, 0.0))
    assert seg.end == pytest.approx((3.5e-3, 3e-3, 0.0))
    assert seg.area == pytest.approx(3e-3) == plate_area(0.75, flat)
    for vessel in (cylinder, box, flat):
        plane = plate_wall(1.0, vessel, 0, height=3e-3)
        assert isinstance(plane, Plane) and plane.area == vessel.cross_section


def _seated(plate, positions, dim=3):
    radii = np.full(len(positions), 1e-3)
    st = gd.State.create(np.asarray(positions)[:, :dim], radii, 2650.0, dim=dim)
    sim = gd.Simulation(st, [gd.Material(density=2650.0, youngs_modulus=1e8)],
                        gd.ContactModel("hertz"), walls=[plate], gravity=(0, 0, 0))
    seat_plate(sim, "plate")
    d, _ = sim.walls.distances(st.positions, np.zeros(st.n, np.int64))
    return sim, d - radii


@pytest.mark.parametrize("plate, dim", [
    (Disk((0.0, 0.0, 50e-3), (0, 0, -1), 3e-3, name="plate"), 3),
    (Segment((-3e-3, -3e-3, 50e-3), (3e-3, -3e-3, 50e-3), name="plate",
             edge=(0.0, 6e-3, 0.0)), 3),
    (Segment((-3e-3, 50e-3), (3e-3, 50e-3), name="plate"), 2),
], ids=["disk", "rectangle", "segment"])
def test_the_plate_is_seated_on_the_grains_under_it_not_those_beside(plate, dim):
    """Grains of radius r = 1 mm: A under the plate (half-width 3 mm) with its top at
    2 mm, B beside it (its centre 2 r beyond the edge) standing higher, at 6 mm, and C
    with its centre 0.6 r beyond the edge at height 2 r: the edge first touches C at
    2 r + sqrt(r^2 - (0.6 r)^2) = 2.8 mm, so the plate sits 1e-3 r above that, C the
    nearest grain to it, and B, beside it, stays clear of it and above it."""
    r = 1e-3
    positions = [(0.0, 0.0, r), (5e-3, 0.0, 5e-3), (-3.6e-3, 0.0, 2 * r)]
    if dim == 2:
        positions = [(x, z, 0.0) for x, _, z in positions]
    sim, gaps = _seated(plate, positions, dim)
    up = dim - 1
    height = sim.walls.geometry[0, up] + sim.walls.offset[0, up]
    assert height == pytest.approx(2.8e-3 + 1e-6, abs=1e-9)
    assert np.argmin(gaps) == 2 and 0 < gaps[2] < 1e-3 * r
    assert gaps[0] == pytest.approx(height - 2e-3, rel=1e-9)
    assert gaps[1] > r and sim.state.positions[1, up] > height


@pytest.mark.parametrize("fraction", [0.0, -0.2, 1.2])
def test_a_plate_fraction_outside_0_1_is_refused(fraction):
    data = copy.deepcopy(PARTIAL)
    data["protocol"]["plate_fraction"] = fraction
    with pytest.raises(ConfigError, match="plate_fraction"):
        validate(data)


def test_a_box_and_a_2d_bed_get_a_rectangle_and_a_segment():
    data = copy.deepcopy(PARTIAL)
    data["walls"]["container"] = {"kind": "box", "lo": [0, 0, 0], "hi": [6e-3, 4e-3, 1e-2]}
    data["protocol"]["plate_fraction"] = 0.5
    config = validate(data)
    made = build.protocol(config)
    walls = build.setup(config, made).walls
    assert isinstance(walls[-1], Segment) and walls[-1].area == pytest.approx(6e-6)
    flat = copy.deepcopy(data)
    flat["run"].update(dim=2, gravity=[0.0, -9.81, 0.0])
    flat["walls"]["container"] = {"kind": "box", "lo": [0, 0], "hi": [6e-3, 1e-2]}
    config = validate(flat)
    walls = build.setup(config, build.protocol(config)).walls
    assert isinstance(walls[-1], Segment) and not np.any(walls[-1].edge)
    assert walls[-1].area == pytest.approx(3e-3)


@pytest.fixture(scope="module")
def partial(tmp_path_factory):
    out = tmp_path_factory.mktemp("partial") / "run"
    return out, execute(validate(PARTIAL), out, show_progress=False, echo=lambda *a: None)


def test_the_partial_plate_carries_the_haversine_on_its_own_area(partial):
    """The plate is a disk of radius f R (area pi (f R)^2); its force over that area
    peaks at Delta sigma plus the plate's weight over it (5 %) at mid-cycle, once it is
    seated (the first cycles punch it into the loose bed, with an overshoot: 60 % at the
    first, 0-16 % at the second from one CPU to another, the bed being chaotic); the
    recorded sigma_plate is the plate's vertical force over the same area."""
    out, results = partial
    area = math.pi * (FRACTION * RADIUS) ** 2
    assert results["plate_area_m2"] == pytest.approx(area, rel=1e-12)
    assert results["plate_fraction"] == FRACTION
    rows = results["cycles"]
    assert [r["cycle"] for r in rows] == [1, 2, 3]
    period = 1 / 50.0
    t0 = rows[0]["time_s"] - period
    series = Series(out / "series.csv").read()
    t = series["time [s]"]
    stress = series["force_plate [N]"] / area
    weight = results["deposition"]["total_weight_N"] / area
    for n in (2,):
        cycle = (t > t0 + n * period) & (t <= t0 + (n + 1) * period)
        peak = np.argmax(stress[cycle])
        assert stress[cycle][peak] == pytest.approx(AMPLITUDE + weight, rel=0.05)
        assert t[cycle][peak] - t0 - n * period == pytest.approx(period / 2, abs=period / 10)
    for r in rows:
        assert 0 < r["sigma_plate_Pa"] < 0.2 * AMPLITUDE
    assert t[-1] == pytest.approx(rows[-1]["time_s"], abs=1e-12)
    assert rows[-1]["sigma_plate_Pa"] == pytest.approx(stress[-1], rel=1e-9)
    settlement = [r["settlement_m"] for r in rows]
    assert 0 < settlement[0] < settlement[-1] < 2e-3


def test_the_grains_beside_the_plate_are_a_free_surface(partial):
    """At the end: no grain within the plate's rim (its centre inside it by a radius)
    straddles the plate (a grain of the heap beside it may have rolled on top of it);
    those below it went down on average; the highest grain beside it (centre beyond the
    rim by a radius) stands more than a radius above it, where a plate over the whole
    width would have pushed it down."""
    out, results = partial
    arrays, _, _, _ = checkpoint.read(out / "checkpoints" / "checkpoint.h5")
    positions, radii = arrays["grains/positions"], arrays["grains/radii"]
    plate = results["cycles"][-1]["plate_height_m"]
    rho = np.hypot(positions[:, 0], positions[:, 1])
    rim = FRACTION * RADIUS
    inside, beside = rho < rim - radii, rho > rim + radii
    under = inside & (positions[:, 2] < plate)
    assert under.sum() > 30 and beside.sum() > 30
    assert np.all(positions[under, 2] + radii[under] < plate + 0.01 * radii[under])
    on_top = inside & ~under
    assert np.all(positions[on_top, 2] - radii[on_top] > plate - 0.01 * radii[on_top])
    assert np.max(positions[beside, 2] + radii[beside]) > plate + np.mean(radii)
    residual = load_residuals(out)[-1, :, 2]
    assert np.mean(residual[under]) < 0 and np.mean(residual[under]) < np.mean(residual[beside])


def test_the_engine_walls_hold_a_disk_plate_and_a_full_plate_stays_a_plane():
    config = validate(PARTIAL)
    made = build.protocol(config)
    state = build.sample(config, made, np.random.default_rng(1))
    engine = build.engine(config, state, made)
    k = engine.walls.index("plate")
    assert engine.walls.kind[k] == DISK
    assert engine.walls.geometry[k, 6] == pytest.approx(FRACTION * RADIUS)
    full = copy.deepcopy(PARTIAL)
    del full["protocol"]["plate_fraction"]
    config = validate(full)
    made = build.protocol(config)
    engine = build.engine(config, state, made)
    k = engine.walls.index("plate")
    assert engine.walls.kind[k] == PLANE
    assert engine.walls.walls[k].area == pytest.approx(math.pi * RADIUS**2)


def test_with_symmetry_planes_the_plate_is_the_whole_containers_and_its_area_the_share():
    """The quarter of a cylinder (planes through its axis): the disk is centred on the
    axis with radius f R, its area the quarter pi (f R)^2 / 4; half a box (plane x = 2 mm
    through its middle): the rectangle is centred on the plane, f times the whole box's
    sides, its area half of it."""
    from graindyn.core.symmetry import Symmetry

    cylinder = Vessel.cylinder((1e-3, 2e-3), 5e-3, 1e-2)
    quarter = cylinder.mirrored([Symmetry("x", 1e-3), Symmetry("y", 2e-3, side=-1)])
    disk = plate_wall(0.8, quarter, 0, height=7e-3)
    assert isinstance(disk, Disk) and disk.radius == pytest.approx(4e-3)
    assert disk.center == pytest.approx((1e-3, 2e-3, 7e-3))
    assert disk.area == pytest.approx(math.pi * 4e-3**2 / 4)
    box = Vessel.box((0.0, 0.0, 0.0), (4e-3, 2e-3, 1e-2), True, 3)
    half = box.mirrored([Symmetry("x", 2e-3)])
    rect = plate_wall(0.5, half, 0, height=3e-3)
    assert rect.start == pytest.approx((1e-3, 0.5e-3, 3e-3))
    assert rect.end == pytest.approx((3e-3, 0.5e-3, 3e-3))
    assert rect.edge == pytest.approx((0.0, 1e-3, 0.0))
    assert rect.area == pytest.approx(1e-6) == 0.5 * plate_area(0.5, box)


def test_the_quarter_model_loads_a_quarter_of_the_disk(tmp_path):
    """PARTIAL cut by the symmetry planes x = 0 and y = 0 (75 grains, a quarter of 300):
    the plate's area is pi (f R)^2 / 4 and, seated (after the three cycles that punch it
    in, 10 % over), it carries Delta sigma plus its weight over that area at mid-cycle
    (5 %)."""
    data = copy.deepcopy(PARTIAL)
    data["walls"]["symmetry"] = [{"axis": "x"}, {"axis": "y"}]
    data["grains"]["count"] = 75
    data["protocol"]["cycles"] = 5       # the small bed settles 0.1 mm a cycle for three
    out = tmp_path / "run"
    results = execute(validate(data), out, show_progress=False, echo=lambda *a: None)
    area = math.pi * (FRACTION * RADIUS) ** 2 / 4
    assert results["plate_area_m2"] == pytest.approx(area, rel=1e-12)
    rows = results["cycles"]
    period = 1 / 50.0
    t0 = rows[0]["time_s"] - period
    series = Series(out / "series.csv").read()
    t = series["time [s]"]
    stress = series["force_plate [N]"] / area
    weight = results["deposition"]["total_weight_N"] / area
    for n in (3, 4):
        cycle = (t > t0 + n * period) & (t <= t0 + (n + 1) * period)
        peak = np.argmax(stress[cycle])
        assert stress[cycle][peak] == pytest.approx(AMPLITUDE + weight, rel=0.05)
        assert t[cycle][peak] - t0 - n * period == pytest.approx(period / 2, abs=period / 10)
