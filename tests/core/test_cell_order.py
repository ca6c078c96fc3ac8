"""cell_order and State.reordered: grains put cell by cell, the physics unchanged."""
import numpy as np
import pytest

import graindyn as gd


def _bed(seed=3, n=60):
    """A loose random cloud of polydisperse spheres falling in a box, in random order."""
    rng = np.random.default_rng(seed)
    side = 6e-3
    lattice = np.stack(np.meshgrid(*[np.arange(4)] * 3, indexing="ij"), -1).reshape(-1, 3)
    positions = 1e-3 + 1.3e-3 * lattice[rng.permutation(len(lattice))[:n]]
    positions += rng.uniform(-5e-5, 5e-5, positions.shape)
    radii = rng.uniform(4e-4, 6e-4, n)
    state = gd.State.create(positions, radii, 2650.0,
                            velocities=rng.normal(scale=0.05, size=(n, 3)))
    walls = gd.box((0, 0, 0), (side, side, side))
    return state, walls


def test_cell_order_sorts_by_cell_keeping_order_within_a_cell():
    rng = np.random.default_rng(0)
    positions = rng.uniform(0.0, 1.0, (500, 3))
    order = gd.cell_order(positions, 0.25)
    assert np.array_equal(np.sort(order), np.arange(500))
    c = np.floor((positions[order] - positions.min(axis=0)) / 0.25).astype(int)
    code = (c[:, 2] * 4 + c[:, 1]) * 4 + c[:, 0]          # x fastest, then y, then z
    assert np.all(np.diff(code) >= 0)
    same = np.diff(code) == 0
    assert np.all(np.diff(order)[same] > 0)               # stable within a cell
    with pytest.raises(ValueError, match="positive"):
        gd.cell_order(positions, 0.0)


def test_reordered_permutes_every_grain_array_alike():
    state, _ = _bed()
    state.fixed[5] = 1
    state.materials[7] = 1
    order = gd.cell_order(state.positions, 1.3e-3)
    moved = state.reordered(order)
    for name, values in state.arrays().items():
        np.testing.assert_array_equal(getattr(moved, name), values[order], err_msg=name)
    assert moved.dim == state.dim and moved.n == state.n
    with pytest.raises(ValueError, match="permutation"):
        state.reordered(np.zeros(state.n, int))


def test_reordered_bed_follows_the_same_trajectory(one_thread):
    """The same grains in another order: the same motion, up to the order of the sums
    of contact forces (round-off)."""
    state, walls = _bed()
    order = gd.cell_order(state.positions, 1.3e-3)
    material = gd.Material(youngs_modulus=1e7, restitution=0.8, friction_sliding=0.4)
    model = gd.ContactModel("hertz", "tsuji", "mindlin")
    runs = []
    for s in (state, state.reordered(order)):
        sim = gd.Simulation(s, [material], model, walls=walls, dt=2e-6, skin=1e-4)
        sim.run(steps=3000)
        assert sim.rebuilds > 1 and sum(sim.dissipated.values()) > 0.0   # they collided
        runs.append(s)
    first, second = runs
    np.testing.assert_allclose(second.positions, first.positions[order], rtol=0, atol=1e-12)
    np.testing.assert_allclose(second.velocities, first.velocities[order], rtol=0, atol=1e-8)
