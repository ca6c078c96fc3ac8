"""The force-network picture (output/network.py): what a 3D slice shows, and a picture
drawn of a real 2D and 3D packing."""
import numpy as np
import pytest

import graindyn as gd
from graindyn.output.network import draw_network, section


def test_a_3d_slice_shows_the_cross_sections_of_the_spheres_it_cuts():
    """Spheres of radius 1 mm centred on the slice plane, 0.6 mm and 3 mm from it: the
    first two are drawn at radii 1 and 0.8 mm (sqrt(1 - 0.36)), the third is not."""
    r = 1e-3
    state = gd.State.create(np.array([[0.0, 0.0, 0.0], [3e-3, 0.6e-3, 0.0],
                                      [6e-3, -3e-3, 0.0], [9e-3, 3e-3, 0.0]]),
                            [r] * 4, 2650.0)
    shown, cut = section(state)                 # middle of the bed: y = 0
    assert list(shown) == [True, True, False, False]
    assert cut[:2] == pytest.approx([r, 0.8 * r])
    flat = gd.State.create(np.zeros((2, 3)) + [[0, 0, 0], [3e-3, 0, 0]], [r, r], 8.0,
                           dim=2)
    shown, cut = section(flat)
    assert shown.all() and cut == pytest.approx([r, r])


@pytest.mark.parametrize("dim", [2, 3])
def test_a_picture_of_a_resting_pair_is_written(dim, tmp_path):
    """Two grains resting on each other on a floor: the picture is written, with the
    marked grain, in 2D and as a slice in 3D."""
    r = 1e-3
    positions = np.array([[0.0, 0.0, r], [0.0, 0.0, 3 * r]]) if dim == 3 \
        else np.array([[0.0, r, 0.0], [0.0, 3 * r, 0.0]])
    state = gd.State.create(positions, [r, r], 2650.0, dim=dim)
    g = (0.0, 0.0, -9.81) if dim == 3 else (0.0, -9.81, 0.0)
    lo, hi = ((-5e-3, -5e-3, 0.0), (5e-3, 5e-3, 1e-2)) if dim == 3 \
        else ((-5e-3, 0.0), (5e-3, 1e-2))
    sim = gd.Simulation(state, [gd.Material(restitution=0.5)],
                        walls=gd.box(lo, hi, dim=dim), gravity=g)
    sim.run(time=0.05)
    assert sim.contacts().normal_force.size == 1
    path = draw_network(sim, tmp_path / "network.png", marked=[1], title="pair")
    assert path.stat().st_size > 1000
