"""Random insertion in periodic boxes: no pair overlaps through a periodic face."""
import numpy as np
import pytest

import graindyn as gd
from graindyn.config import build, validate
from graindyn.protocols.prepare import BoxRegion, random_insertion


def _overlap_free(pos, radii, length, periodic):
    """True when no pair of grains overlaps, separations taken as minimum images along
    the ``periodic`` axes of period ``length`` [m] (all pairs, with numpy)."""
    d = pos[:, None] - pos[None]
    for axis in periodic:
        d[..., axis] -= length[axis] * np.round(d[..., axis] / length[axis])
    gap = np.linalg.norm(d, axis=-1) - radii[:, None] - radii[None]
    np.fill_diagonal(gap, np.inf)
    return gap.min() >= -1e-15


@pytest.mark.parametrize("dim, n, fraction", [(3, 600, 0.30), (2, 400, 0.45)])
def test_fully_periodic_insertion_has_no_overlap_under_minimum_image(rng, dim, n, fraction):
    radii = gd.sample_radii(n, "uniform", rng, d_min=0.8e-3, d_max=1.2e-3)
    solid = np.sum(4 / 3 * np.pi * radii**3 if dim == 3 else np.pi * radii**2)
    side = (solid / fraction) ** (1 / dim)
    region = BoxRegion((0.0,) * dim, (side,) * dim)
    pos, r = random_insertion(radii, region, rng, dim, periodic=range(dim))
    assert _overlap_free(pos, r, np.full(3, side), range(dim))
    # no margin at the faces: grains cross every periodic face
    for axis in range(dim):
        assert np.all((pos[:, axis] >= 0) & (pos[:, axis] <= side))
        assert np.any(pos[:, axis] < r) and np.any(pos[:, axis] > side - r)


def test_periodic_x_reaches_both_x_faces(rng):
    radii = gd.sample_radii(300, "uniform", rng, d_min=0.9e-3, d_max=1.1e-3)
    region = BoxRegion((0.0, 0.0, 0.0), (8e-3, 8e-3, 30e-3))
    pos, r = random_insertion(radii, region, rng, periodic=[0])
    assert np.any(pos[:, 0] < r) and np.any(pos[:, 0] > 8e-3 - r)
    assert np.all(pos[:, 1] - r >= -1e-15) and np.all(pos[:, 1] + r <= 8e-3 + 1e-15)
    assert _overlap_free(pos, r, np.array([8e-3, 0, 0]), [0])


def test_bad_periodic_axes_are_refused(rng):
    radii = np.full(10, 0.5e-3)
    with pytest.raises(ValueError, match="periodic = \\(2,\\)"):
        random_insertion(radii, BoxRegion((0, 0), (5e-3, 5e-3)), rng, dim=2, periodic=[2])
    with pytest.raises(ValueError, match="periodic axis 0: the period"):
        random_insertion(radii, BoxRegion((0, 0, 0), (0.8e-3, 5e-3, 5e-3)), rng,
                         periodic=[0])


def test_config_sample_is_periodic_where_the_box_spans_the_period():
    """build.sample passes walls.periodic on: x spans the box's [lo, hi] and is
    periodic in the insertion, z does not and keeps its margins."""
    config = validate({
        "run": {"name": "periodic", "seed": 3},
        "grains": {"count": 200, "material": "quartz",
                   "diameter": {"min": 0.9e-3, "max": 1.1e-3}},
        "materials": [{"name": "quartz", "restitution": 0.8}],
        "contact": {"normal": "hertz", "damping": "tsuji", "tangential": "mindlin"},
        "walls": {"material": "quartz", "periodic": [[0, 0.0, 6e-3], [2, 0.0, 1.0]],
                  "container": {"kind": "box", "lo": [0, 0, 0], "hi": [6e-3, 6e-3, 40e-3]}},
        "protocol": {"max_time": 0.01},
    })
    state = build.sample(config, build.protocol(config), np.random.default_rng(1))
    pos, r = state.positions, state.radii
    assert np.any(pos[:, 0] < r) and np.any(pos[:, 0] > 6e-3 - r)
    assert np.all(pos[:, 2] - r >= -1e-15)
    assert _overlap_free(pos, r, np.array([6e-3, 0, 0]), [0])
