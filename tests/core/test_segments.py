"""Finite walls (core.walls.Segment): the distance and normal to a 2D segment and a 3D
rectangle against hand-computed values, the NumPy twin against the compiled function,
a disk at rest on a segment and on the two lips of a narrow orifice against statics, a
disk falling through a wide orifice, and [[walls.segments]] in a config."""
import math

import numpy as np
import pytest

import graindyn as gd
from graindyn.config import ConfigError, validate
from graindyn.config import build
from graindyn.engines.event_driven.engine import EventDriven
from graindyn.core.walls import (SEGMENT, Cylinder, Plane, Segment, Walls, wall_distance,
                                 wall_reach)

R = 1e-3
RHO = 2650.0
G = 9.81


def _compiled(walls, k, point):
    d, nx, ny, nz = wall_distance(walls.kind, walls.geometry, walls.offset, k, *point)
    return d, np.array([nx, ny, nz])


# segment (1, 1) -> (3, 1) in 2D, and (0, 0) -> (3, 4) slanted: point, distance, normal
SEGMENT_CASES = [
    ("face above", 0, (2.0, 1.5, 0.0), 0.5, (0.0, 1.0, 0.0)),
    ("face below", 0, (2.0, 0.2, 0.0), 0.8, (0.0, -1.0, 0.0)),
    ("start, along the line", 0, (0.0, 1.0, 0.0), 1.0, (-1.0, 0.0, 0.0)),
    ("beyond the start", 0, (0.7, 1.4, 0.0), 0.5, (-0.6, 0.8, 0.0)),
    ("beyond the end, below", 0, (3.3, 0.6, 0.0), 0.5, (0.6, -0.8, 0.0)),
    ("end, along the line", 0, (4.0, 1.0, 0.0), 1.0, (1.0, 0.0, 0.0)),
    ("slanted, face", 1, (-0.1, 3.2, 0.0), 2.0, (-0.8, 0.6, 0.0)),
    ("slanted, over the start", 1, (-4.0, 3.0, 0.0), 5.0, (-0.8, 0.6, 0.0)),
    ("slanted, over the end, other side", 1, (7.0, 1.0, 0.0), 5.0, (0.8, -0.6, 0.0)),
    ("slanted, beyond the end", 1, (6.0, 8.0, 0.0), 5.0, (0.6, 0.8, 0.0)),
]
# rectangle corner (1, 2, 3), edges (2, 0, 0) and (0, 1, 0): x in [1, 3], y in [2, 3], z = 3
RECTANGLE_CASES = [
    ("face above", (2.0, 2.5, 3.3), 0.3, (0.0, 0.0, 1.0)),
    ("face below", (2.0, 2.5, 2.7), 0.3, (0.0, 0.0, -1.0)),
    ("edge y = 3", (2.0, 3.3, 3.4), 0.5, (0.0, 0.6, 0.8)),
    ("edge x = 1, below", (0.7, 2.5, 2.6), 0.5, (-0.6, 0.0, -0.8)),
    ("corner (3, 2), in the plane", (3.3, 1.6, 3.0), 0.5, (0.6, -0.8, 0.0)),
    ("corner (3, 3)", (3.2, 3.2, 3.1), 0.3, (2 / 3, 2 / 3, 1 / 3)),
    ("beyond edge x = 3, in the plane", (4.0, 2.5, 3.0), 1.0, (1.0, 0.0, 0.0)),
]


def _segments():
    return Walls([Segment((1.0, 1.0), (3.0, 1.0)), Segment((0.0, 0.0, 0.0), (3.0, 4.0, 0.0)),
                  Segment((1.0, 2.0, 3.0), (3.0, 2.0, 3.0), edge=(0.0, 1.0, 0.0))])


@pytest.mark.parametrize("what, k, point, distance, normal", SEGMENT_CASES,
                         ids=[c[0] for c in SEGMENT_CASES])
def test_distance_to_a_segment(what, k, point, distance, normal):
    walls = _segments()
    d, n = _compiled(walls, k, point)
    assert d == pytest.approx(distance, abs=1e-12)
    assert n == pytest.approx(normal, abs=1e-12)
    twin_d, twin_n = walls.distances(np.array([point]), np.array([k]))
    assert twin_d[0] == pytest.approx(d, abs=1e-14)
    assert twin_n[0] == pytest.approx(n, abs=1e-14)


@pytest.mark.parametrize("what, point, distance, normal", RECTANGLE_CASES,
                         ids=[c[0] for c in RECTANGLE_CASES])
def test_distance_to_a_rectangle(what, point, distance, normal):
    walls = _segments()
    d, n = _compiled(walls, 2, point)
    assert d == pytest.approx(distance, abs=1e-12)
    assert n == pytest.approx(normal, abs=1e-12)
    twin_d, twin_n = walls.distances(np.array([point]), np.array([2]))
    assert twin_d[0] == pytest.approx(d, abs=1e-14)
    assert twin_n[0] == pytest.approx(n, abs=1e-14)


def test_a_point_on_the_wall_gets_its_face_normal_and_a_moved_wall_moves_its_distances():
    walls = _segments()
    assert _compiled(walls, 0, (2.0, 1.0, 0.0))[0] == 0.0
    assert _compiled(walls, 0, (2.0, 1.0, 0.0))[1] == pytest.approx((0.0, 1.0, 0.0))
    assert _compiled(walls, 2, (2.0, 2.5, 3.0))[1] == pytest.approx((0.0, 0.0, 1.0))
    d, n = walls.distances(np.array([[2.0, 1.0, 0.0], [2.0, 2.5, 3.0]]), np.array([0, 2]))
    assert d == pytest.approx([0.0, 0.0]) and n == pytest.approx(np.array([[0, 1, 0], [0, 0, 1]]))
    shift = np.array([0.3, -0.2, 0.1])
    walls.offset[2] = shift
    for _, point, distance, normal in RECTANGLE_CASES:
        d, n = _compiled(walls, 2, np.asarray(point) + shift)
        assert d == pytest.approx(distance, abs=1e-12) and n == pytest.approx(normal, abs=1e-12)


def test_numpy_twin_equals_the_compiled_function_and_planes_and_cylinders_are_unchanged():
    """Random points against every kind; planes and cylinders still give, to the bit,
    the arithmetic they had with a 7-column geometry."""
    rng = np.random.default_rng(4)
    walls = Walls([Plane((0.1, 0.2, 0.3), (1.0, 2.0, 2.0)),
                   Cylinder((0.5, -0.5, 0.0), (0.0, 0.6, 0.8), 1.3),
                   Segment((-1.0, 0.5), (1.5, -0.5)),
                   Segment((0.0, 0.0, 0.0), (0.0, 1.0, 1.0), edge=(2.0, 0.0, 0.0))])
    assert walls.geometry.shape == (4, 10)
    assert not walls.geometry[:2, 7:].any()
    points = rng.uniform(-3, 3, (200, 3))
    points[::3, 2] = 0.0
    for k in range(len(walls)):
        twin_d, twin_n = walls.distances(points, np.full(len(points), k))
        for p, td, tn in zip(points, twin_d, twin_n):
            d, n = _compiled(walls, k, p)
            assert td == pytest.approx(d, rel=1e-12, abs=1e-15)
            assert tn == pytest.approx(n, rel=1e-12, abs=1e-15)
            if k > 1:
                continue
            g = walls.geometry[k]                  # the pre-segment arithmetic
            px, py, pz = p[0] - g[0], p[1] - g[1], p[2] - g[2]
            along = px * g[3] + py * g[4] + pz * g[5]
            if k == 0:
                assert (d, *n) == (along, g[3], g[4], g[5])
                continue
            rx, ry, rz = px - along * g[3], py - along * g[4], pz - along * g[5]
            rho = math.sqrt(rx * rx + ry * ry + rz * rz)
            inverse = 1.0 / rho
            assert (d, *n) == (g[6] - rho, -rx * inverse, -ry * inverse, -rz * inverse)


def test_a_degenerate_segment_is_refused():
    with pytest.raises(ValueError, match="start and end coincide"):
        Segment((1.0, 2.0), (1.0, 2.0))
    with pytest.raises(ValueError, match="perpendicular"):
        Segment((0, 0, 0), (1, 0, 0), edge=(1, 1, 0))
    with pytest.raises(ValueError, match="finite"):
        Segment((0, 0, 0), (math.inf, 0, 0))
    assert Segment((0, 0), (3, 4)).area == 5.0
    assert Segment((0, 0, 0), (2, 0, 0), edge=(0, 0, 3)).area == 6.0


def test_open_ends_touch_only_grains_over_the_wall():
    """Open ends: over the face the distance of round ends; beyond an end or edge no
    contact (inf), in the compiled function and its NumPy twin alike; wall_reach still
    gives the round ends' distance, so the lists keep a grain that may come over it."""
    walls = Walls([Segment((1.0, 1.0), (3.0, 1.0), ends="open"),
                   Segment((1.0, 2.0, 3.0), (3.0, 2.0, 3.0), edge=(0.0, 1.0, 0.0),
                           ends="open"),
                   Segment((1.0, 1.0), (3.0, 1.0))])
    over = [(0, (2.0, 1.5, 0.0), 0.5), (0, (1.0, 0.7, 0.0), 0.3), (1, (2.0, 2.5, 2.7), 0.3)]
    beyond = [(0, (0.9, 1.2, 0.0)), (0, (3.3, 0.6, 0.0)), (1, (2.0, 3.3, 3.4)),
              (1, (3.2, 3.2, 3.1))]
    for k, point, distance in over:
        d, n = _compiled(walls, k, point)
        assert d == pytest.approx(distance, abs=1e-12)
        assert abs(n[1 if k == 0 else 2]) == pytest.approx(1.0)
    for k, point in beyond:
        assert _compiled(walls, k, point)[0] == math.inf
        twin_d, twin_n = walls.distances(np.array([point]), np.array([k]))
        assert twin_d[0] == math.inf and twin_n[0] == pytest.approx([1.0, 0.0, 0.0])
    rng = np.random.default_rng(7)
    points = rng.uniform(0, 4, (300, 3))
    points[:, 2] = rng.uniform(2.5, 3.5, 300)
    for k in range(3):
        twin_d, _ = walls.distances(points, np.full(len(points), k))
        for p, td in zip(points, twin_d):
            d, _ = _compiled(walls, k, p)
            assert td == pytest.approx(d, rel=1e-12, abs=1e-15)
            reach = wall_reach(walls.kind, walls.geometry, walls.offset, k, *p)
            round_d = _compiled(walls, 2, p)[0] if k != 1 else None
            if k == 0:
                assert reach == round_d and (d == math.inf or d == round_d)
    assert walls.geometry[:, 6] == pytest.approx([1.0, 1.0, 0.0])
    with pytest.raises(ValueError, match="ends must be one of"):
        Segment((0, 0), (1, 0), ends="square")


# ---------------------------------------------------------------- dynamics (2D disks)
def _disk(x, y, walls):
    st = gd.State.create([[x, y]], [R], RHO, dim=2)
    mat = gd.Material(density=RHO, youngs_modulus=1e8, poisson_ratio=0.3, restitution=0.3)
    return gd.Simulation(st, [mat], gd.ContactModel("hertz", "tsuji"), walls=walls,
                         gravity=(0.0, -G, 0.0))


def test_a_disk_comes_to_rest_on_a_segment_carrying_its_weight():
    """Statics: resting on a horizontal segment, the disk's centre is R (less the small
    elastic overlap) above it and the segment carries its weight."""
    sim = _disk(0.0, 3 * R, [Segment((-5 * R, 0.0), (5 * R, 0.0), name="shelf")])
    sim.run(time=0.1)
    st = sim.state
    weight = st.masses[0] * G
    assert np.linalg.norm(st.velocities[0]) < 1e-4
    assert 0.98 * R < st.positions[0, 1] < R
    assert st.positions[0, 0] == pytest.approx(0.0, abs=1e-12)
    assert sim.walls.normal_force(0) == pytest.approx(weight, rel=1e-3)
    assert sim.walls.force[0] == pytest.approx([0.0, -weight, 0.0], rel=1e-3, abs=1e-9 * weight)


def test_a_disk_wider_than_the_orifice_rests_on_both_lips():
    """Two segments end at x = -0.6 R and 0.6 R: the disk rests on the two end points,
    its centre about sqrt(R^2 - (0.6 R)^2) = 0.8 R above them; each lip pushes along the
    line from its end point to the centre, at cos(theta) = y / sqrt(0.36 R^2 + y^2) from
    the vertical, so carries m g / (2 cos(theta)) (statics)."""
    h = 0.6 * R
    walls = [Segment((-6 * R, 0.0), (-h, 0.0), name="left"),
             Segment((h, 0.0), (6 * R, 0.0), name="right")]
    sim = _disk(0.0, 2 * R, walls)
    sim.run(time=0.1)
    st = sim.state
    weight = st.masses[0] * G
    assert np.linalg.norm(st.velocities[0]) < 1e-4
    y = st.positions[0, 1]
    assert 0.95 * 0.8 * R < y < 0.8 * R
    assert st.positions[0, 0] == pytest.approx(0.0, abs=1e-9 * R)
    cos = y / math.hypot(h, y)
    for k, side in ((0, -1), (1, 1)):
        assert sim.walls.normal_force(k) == pytest.approx(weight / (2 * cos), rel=1e-3)
        fx, fy = sim.walls.force[k, :2]            # the grain pushes the lip outwards
        assert side * fx > 0 and fy < 0
    assert sim.walls.force[:, 1].sum() == pytest.approx(-weight, rel=1e-3)


def test_a_disk_at_the_lip_of_a_wide_orifice_is_deflected_and_falls_through():
    """The gap (3 R) is wider than the disk (2 R); dropped with its centre 0.6 R off the
    gap's axis, the disk hits the end point of the right segment, which pushes it to the
    left, and it falls through."""
    walls = [Segment((-6 * R, 0.0), (-1.5 * R, 0.0), name="left"),
             Segment((1.5 * R, 0.0), (6 * R, 0.0), name="right")]
    sim = _disk(0.6 * R, 2 * R, walls)
    touched = []
    sim.run(time=0.06, every=[(gd.Periodic(steps=1),
                               lambda s: touched.append(s.walls.normal_force(1)))])
    st = sim.state
    assert max(touched) > 0                        # it touched the lip
    assert st.velocities[0, 0] < 0                 # pushed away from the end point
    assert st.positions[0, 1] < -5 * R             # and fell through the orifice
    assert sim.walls.normal_force(0) == 0.0 and sim.walls.normal_force(1) == 0.0


def test_a_disk_wider_than_an_orifice_of_open_ends_falls_through_it():
    """The orifice of test_a_disk_wider_than_the_orifice_rests_on_both_lips with open
    ends: the disk's centre is over the gap, so neither segment touches it, and it
    falls freely (y(t) = y0 - g t^2 / 2) through the gap narrower than itself."""
    h = 0.6 * R
    walls = [Segment((-6 * R, 0.0), (-h, 0.0), name="left", ends="open"),
             Segment((h, 0.0), (6 * R, 0.0), name="right", ends="open")]
    sim = _disk(0.0, 2 * R, walls)
    sim.run(time=0.02)
    st = sim.state
    assert st.positions[0, 1] == pytest.approx(2 * R - 0.5 * G * st.time**2, rel=1e-6)
    assert st.positions[0, 0] == 0.0
    assert sim.walls.normal_force(0) == 0.0 and sim.walls.normal_force(1) == 0.0


def test_the_event_driven_engine_refuses_open_ends():
    st = gd.State.create([[0.0, 2 * R]], [R], RHO, dim=2)
    with pytest.raises(ValueError, match="open ends"):
        EventDriven(st, [gd.Material(density=RHO)],
                                 walls=[Segment((-R, 0.0), (R, 0.0), ends="open")])


# ---------------------------------------------------------------- config
def _config(**segment):
    seg = {"name": "lip", "start": [0.0, 4e-3], "end": [2e-3, 4e-3], **segment}
    return {
        "run": {"name": "silo", "dim": 2, "gravity": [0.0, -9.81, 0.0]},
        "grains": {"count": 4, "material": "glass",
                   "diameter": {"min": 0.9e-3, "max": 1.1e-3}},
        "materials": [{"name": "glass", "restitution": 0.5},
                      {"name": "steel", "density": 7800.0, "youngs_modulus": 2e9,
                       "restitution": 0.5}],
        "walls": {"material": "steel",
                  "container": {"kind": "box", "lo": [0, 0], "hi": [6e-3, 30e-3]},
                  "segments": [seg]},
        "protocol": {"max_time": 0.01},
    }


def test_a_config_with_segments_validates_and_builds_a_simulation():
    config = validate(_config(material="glass"))
    seg = config.walls.segments[0]
    assert seg.name == "lip" and seg.edge is None
    walls, _ = build.walls(config)
    made = [w for w in walls if isinstance(w, Segment)]
    assert len(made) == 1 and made[0].material == config.material_index("glass")
    assert made[0].area == pytest.approx(2e-3)
    protocol = build.protocol(config)
    state = build.sample(config, protocol, np.random.default_rng(1))
    engine = build.engine(config, state, protocol)
    k = engine.walls.index("lip")
    assert engine.walls.kind[k] == SEGMENT
    assert engine.walls.geometry[k] == pytest.approx([0, 4e-3, 0, 2e-3, 0, 0, 0, 0, 0, 0])
    three = _config(start=[0, 0, 4e-3], end=[2e-3, 0, 4e-3], edge=[0, 1e-3, 0])
    three["run"] = {"dim": 3}
    three["walls"]["container"] = {"kind": "box", "lo": [0, 0, 0], "hi": [6e-3] * 3}
    assert validate(three).walls.segments[0].edge == (0, 1e-3, 0)
    opened = build.walls(validate(_config(ends="open")))[0]
    assert [w.ends for w in opened if isinstance(w, Segment)] == ["open"]


@pytest.mark.parametrize("segment, message", [
    ({"end": [0.0, 4e-3]}, "start and end coincide"),
    ({"end": [2e-3, 4e-3, 1e-3]}, "a 2D segment lies in the x-y plane"),
    ({"edge": [0.0, 0.0, 1e-3]}, "a 2D segment lies in the x-y plane"),
    ({"material": "wood"}, "walls.segments.0.material = 'wood' is not a material"),
    ({"end": [math.nan, 4e-3]}, "finite"),
    ({"ends": "square"}, "ends"),
])
def test_a_bad_segment_is_refused_with_a_clear_message(segment, message):
    with pytest.raises(ConfigError, match=message):
        validate(_config(**segment))


def test_a_3d_segment_needs_a_perpendicular_edge():
    three = _config(start=[0, 0, 4e-3], end=[2e-3, 0, 4e-3])
    three["run"] = {"dim": 3}
    three["walls"]["container"] = {"kind": "box", "lo": [0, 0, 0], "hi": [6e-3] * 3}
    with pytest.raises(ConfigError, match="a 3D segment is a rectangle"):
        validate(three)
    three["walls"]["segments"][0]["edge"] = [1e-3, 1e-3, 0.0]
    with pytest.raises(ConfigError, match="perpendicular"):
        validate(three)
    three["walls"]["segments"][0]["edge"] = [0.0, 0.0, 0.0]
    with pytest.raises(ConfigError, match="edge must be non-zero"):
        validate(three)
