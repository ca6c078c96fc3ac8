"""The CPU's batched, vectorized law (engines/soft/law_loop.py, contacts._pair_block; in 2D
planar._planar_rows) against
the contact-by-contact evaluation (contacts.pair_row, the GPU's path): on a dense,
polydisperse, two-material bed with spinning grains and random contact histories,
every model composition gives the same pair forces and histories, to the bit, across
several batches of contacts and three blocks of grains; and the same force and torque
on every grain once each grain's sums are completed by the pairs it does not hold
(the CPU adds a pair to both grains when they share a block, the GPU only to the
first), to rounding."""
import numba
import numpy as np
import pytest

import graindyn as gd
from graindyn.engines.soft.contacts import (PAIRS, PLANAR, WALLS, contact_forces, pair_row,
                                            wall_row)
from graindyn.engines.soft.law_loop import prepare, workspace

MODELS = [("hertz", "tsuji", "mindlin"), ("hooke", "linear", "cundall_strack"),
          ("hertz", "viscoelastic", "oquendo", "none", "oquendo"),
          ("hertz", "viscoelastic", "oquendo_literal", "none", "oquendo"),
          ("hertz", "karrech", "karrech"), ("hertz", "tsuji", "coulomb", "epsd", "epsd"),
          ("walton_braun", "none", "mindlin", "constant", "constant")]
MATERIAL = dict(youngs_modulus=1e7, restitution=0.7, kn=2e3, kt=1e3, friction_sliding=0.4,
                friction_static=0.5, friction_rolling=0.05, friction_twisting=0.05,
                gamma_n=2e5, gamma_nt=1e3, slip_threshold=1e-4, alpha_n=0.44, alpha_t=0.44,
                rolling_stiffness=1.0, rolling_damping=1e-4, twisting_stiffness=1e-4,
                twisting_damping=1e-8, tangential_damping=0.1)


@numba.njit
def one_by_one(model, params, g, periodic, p, dt):
    for i in range(g.positions.shape[0]):
        pair_row(i, model, params, g.positions, g.velocities, g.angular_velocities, g.radii,
                 g.masses, g.materials, g.fixed, periodic.flag, periodic.length, p.start,
                 p.partners, p.history, p.force, p.own, p.torque_j, g.max_overlap, dt)


def bed(model, walls=(), dim=3):
    """400 spheres (disks in the plane z = 0 when dim = 2) of two materials."""
    rng = np.random.default_rng(3)
    pos = rng.uniform(0.0, 6e-3, (400, 3))
    velocities = rng.normal(scale=0.1, size=(400, 3))
    spins = rng.normal(scale=50.0, size=(400, 3))
    if dim == 2:
        pos[:, 2] = velocities[:, 2] = spins[:, 0] = spins[:, 1] = 0.0
    state = gd.State.create(pos, rng.uniform(0.4e-3, 0.7e-3, 400), 2650.0,
                            materials=rng.integers(0, 2, 400), dim=dim)
    state.velocities[:] = velocities
    state.angular_velocities[:] = spins
    materials = [gd.Material(**MATERIAL), gd.Material(**dict(MATERIAL, youngs_modulus=3e7))]
    sim = gd.Simulation(state, materials, gd.ContactModel(*model), walls=walls, dt=1e-7,
                        allow_large_dt=True, overlap_limit=10.0,
                        gravity=(0.0, -9.81, 0.0) if dim == 2 else (0.0, 0.0, -9.81))
    sim.run(steps=1)
    if dim == 2:      # random histories would leave the plane: let them build up instead
        sim.run(steps=20)
        return sim
    m = int(sim.pairs.start[-1])
    sim.pairs.history[:m] = rng.normal(scale=1e-6, size=sim.pairs.history[:m].shape) \
        * (rng.random((m, 1)) < 0.6)
    return sim


@numba.njit
def walls_one_by_one(model, params, g, w, dt):
    for i in range(g.positions.shape[0]):
        wall_row(i, model, params, g.positions, g.velocities, g.angular_velocities, g.radii,
                 g.masses, g.materials, w.kind, w.geometry, w.offset, w.velocity, w.material,
                 w.wall_start, w.wall_ids, w.wall_history, w.contact_force, w.contact_torque,
                 g.max_overlap, dt)


def totals(sim, own, force, torque_j, nblock):
    """Force and torque (N, 6) on each grain: own[i] plus, for each pair (i, j) whose j
    does not hold it (j in another block; nblock 0: never), -force and torque_j."""
    n = sim.state.n
    start, partners = sim.pairs.start, sim.pairs.partners
    m = int(start[n])
    first = np.repeat(np.arange(n), np.diff(start))
    second = partners[:m].astype(np.int64)
    total = own.copy()
    if nblock:
        block = np.searchsorted([(b + 1) * n // nblock for b in range(nblock)], np.arange(n),
                                side="right")
        cross = block[first] != block[second]
    else:
        cross = np.ones(m, bool)
    np.add.at(total[:, :3], second[cross], -force[:m][cross])
    np.add.at(total[:, 3:], second[cross], torque_j[:m][cross])
    return total


def forces_args(sim, law):
    """contact_forces' arguments up to max_overlap, from a Simulation's arrays."""
    g, w, p, per = sim._grains(), sim._walls(), sim.pairs, sim._periodic()
    return (sim.model_ids, sim.params, law, g.positions, g.velocities, g.angular_velocities,
            g.radii, g.masses, g.materials, g.fixed, per.flag, per.length, p.start,
            p.partners, p.scratch_partners, p.history, p.force, p.torque_j, w.kind,
            w.geometry, w.offset, w.velocity, w.material, w.wall_start, w.wall_ids,
            w.scratch_wall_ids, w.wall_history, w.contact_force, w.contact_torque, p.own,
            g.max_overlap)


def pairs_only(sim, law, nblock):
    """The pair forces alone (contacts.contact_forces, PAIRS, and PLANAR in 2D),
    dt = 1e-7 s."""
    contact_forces(*forces_args(sim, law), 1e-7, nblock,
                   PAIRS | (PLANAR if sim.state.dim == 2 else 0))


@pytest.mark.parametrize("model, dim", [(m, 3) for m in MODELS] + [
    (("hooke", "linear", "cundall_strack"), 2), (("walton_braun", "none", "coulomb"), 2)],
    ids=lambda x: ",".join(x) if isinstance(x, tuple) else f"{x}d")
def test_batched_law_equals_contact_by_contact(model, dim, one_thread):
    """In 2D the pairs are evaluated one at a time as they are walked
    (planar._planar_rows, compiled for the model), with the springs' scalar form: the same forces and
    histories as pair_row, to the bit."""
    sim = bed(model, dim=dim)
    touching = len(sim.contacts()[0])
    assert touching > 300              # several batches of 128
    g, p, per = sim._grains(), sim.pairs, sim._periodic()
    kept = ("history", "force", "own", "torque_j")
    saved = {k: getattr(p, k).copy() for k in kept}
    saved_overlap = g.max_overlap.copy()
    nblock = 3
    law = prepare(workspace(sim._law.address, nblock, sim.history_size, sim._law.planar),
                  sim.params, p.partners.size)
    pairs_only(sim, law, nblock)
    batched = {k: getattr(p, k).copy() for k in kept}
    deepest = g.max_overlap.max()            # kept by block (contacts.keep_worst)
    for k in kept:
        getattr(p, k)[...] = saved[k]
    g.max_overlap[...] = saved_overlap
    one_by_one(sim.model_ids, sim.params, g, per, p, 1e-7)
    for name in ("history", "force"):
        assert np.array_equal(batched[name], getattr(p, name)), name
    assert deepest == g.max_overlap.max() > 0.0
    assert np.count_nonzero(p.force) > 0
    mine = totals(sim, batched["own"], batched["force"], batched["torque_j"], nblock)
    reference = totals(sim, p.own, p.force, p.torque_j, 0)
    scale = np.abs(reference).max(axis=0)
    assert np.all(np.abs(mine - reference) <= 1e-13 * scale)
    assert not np.array_equal(batched["own"], p.own)  # the CPU did add pairs to both grains


def test_open_pair_with_only_a_stale_torque_is_cleared(one_thread):
    """A touching pair of one block stores its force but not the torque on its second
    grain (own has it), so after a rebuild the slot of an open pair may hold a zero force
    (a repulsive-only law at rest gives exactly zero) and an old torque: the pair loop
    must clear it, or the gather adds it to a grain of another block."""
    sim = bed(("hooke", "linear", "cundall_strack"))
    g, p = sim._grains(), sim.pairs
    n, start, partners = sim.state.n, p.start, p.partners
    nblock = 2
    first = np.repeat(np.arange(n), np.diff(start))
    m = int(start[n])
    separation = np.linalg.norm(g.positions[first] - g.positions[partners[:m]], axis=1)
    open_ = separation > g.radii[first] + g.radii[partners[:m]]
    cross = (first < n // 2) & (partners[:m] >= n // 2)
    k = int(np.flatnonzero(open_ & cross)[0])
    p.history[k] = 0.0
    p.force[k] = 0.0
    p.torque_j[k] = (1e-9, 2e-9, 3e-9)
    law = prepare(workspace(sim._law.address, nblock, sim.history_size, sim._law.planar),
                  sim.params, p.partners.size)
    pairs_only(sim, law, nblock)
    assert np.all(p.torque_j[k] == 0.0)


@pytest.mark.parametrize("model", MODELS[:4], ids=lambda m: ",".join(m))
def test_batched_walls_equal_contact_by_contact(model, one_thread):
    """The wall contacts through the same law loop (contacts._wall_block) against
    wall_row, one contact after the other: forces, torques and histories to the bit,
    several batches, walls moving, two materials (the walls of the second)."""
    walls = gd.box((0.0, 0.0, 0.0), (6e-3, 6e-3, 6e-3), material=1)
    sim = bed(model, walls)
    sim.walls.velocity[:] = np.random.default_rng(5).normal(scale=0.05,
                                                            size=sim.walls.velocity.shape)
    g, w = sim._grains(), sim._walls()
    m = int(w.wall_start[-1])
    w.wall_history[:m] = np.random.default_rng(4).normal(scale=1e-6,
                                                         size=w.wall_history[:m].shape)
    kept = ("wall_history", "contact_force", "contact_torque")
    saved = {k: getattr(w, k).copy() for k in kept}
    saved_overlap = g.max_overlap.copy()
    touching = len(sim.wall_contacts().grain)
    assert touching > 150               # two batches and more
    own = sim.pairs.own
    own[...] = np.random.default_rng(6).normal(size=own.shape)
    own_before = own.copy()
    contact_forces(*forces_args(sim, sim._law), 1e-7, sim.block_scratch.size, WALLS)
    batched = {k: getattr(w, k).copy() for k in kept}
    batched_overlap = g.max_overlap.copy()
    for k in kept:
        getattr(w, k)[...] = saved[k]
    g.max_overlap[...] = saved_overlap
    walls_one_by_one(sim.model_ids, sim.params, g, w, 1e-7)
    for name in kept:
        assert np.array_equal(batched[name], getattr(w, name)), name
    assert batched_overlap.max() == g.max_overlap.max() > 0.0  # by block, by grain: one maximum
    assert np.count_nonzero(w.contact_force) > 0
    # and added to their grains' sums, after what was there
    grain = np.repeat(np.arange(sim.state.n), np.diff(w.wall_start))
    added = own_before.copy()
    for q, i in enumerate(grain):
        added[i] += np.concatenate((batched["contact_force"][q], batched["contact_torque"][q]))
    assert np.array_equal(own, added)


def test_block_count_keeps_tiny_systems_on_one_block():
    """One block on one thread and below SERIAL grains per thread (no parallel region);
    else one per thread at least, about 2048 grains each, at most two per thread and
    MAX_BLOCKS."""
    from graindyn.engines.soft.contacts import MAX_BLOCKS, SERIAL, block_count
    assert block_count(10**6, 1) == 1
    assert block_count(200, 2) == 1
    assert block_count(2 * SERIAL - 1, 2) == 1
    assert block_count(2 * SERIAL, 2) == 2
    assert block_count(1000, 2) == 2
    assert block_count(10_000, 2) == 4
    assert block_count(100_000, 2) == 4
    assert block_count(10**7, 4) == 8
    assert block_count(10**7, MAX_BLOCKS) == MAX_BLOCKS


def test_workspace_rows_start_on_cache_lines():
    """Every block's workspace and every row of it (STRIDE doubles) start on a 64-byte
    boundary, so the law loop's 512-bit accesses never straddle two cache lines.  A new
    workspace holds zeros, and no pair-table row (TABLE: -1)."""
    from graindyn.engines.soft.law_loop import STRIDE, TABLE
    for blocks in (1, 3, 7):
        work = workspace(0, blocks, 4).work
        rows = work.reshape(blocks, -1, STRIDE)
        assert work.flags.c_contiguous and (rows[:, TABLE] == -1.0).all()
        assert not np.delete(rows, TABLE, axis=1).any()
        for b in range(blocks):
            assert work[b].ctypes.data % 64 == 0
        assert (STRIDE * work.itemsize) % 64 == 0


def test_grains_of_the_walks_are_refilled_before_every_chunk(one_thread):
    """The walks read each pair's and wall candidate's grain from arrays the rebuild
    fills (neighbors.list_owners, kept in the rebuild's scratch between rebuilds).
    Scratch overwritten between two runs (as a snapshot of another version or the GPU
    may leave it) must not change the trajectory: Simulation refills them."""
    walls = gd.box((0.0, 0.0, 0.0), (6e-3, 6e-3, 6e-3))
    runs = []
    for scribble in (False, True):
        sim = bed(("hertz", "tsuji", "mindlin"), walls)
        sim.run(steps=20)
        if scribble:
            sim.pairs.scratch_partners[:] = 0
            sim.wall_pairs.scratch_ids[:] = 0
        sim.run(steps=20)
        runs.append(sim)
    clean, scribbled = runs
    assert clean.rebuilds == scribbled.rebuilds
    assert len(clean.wall_contacts().grain) > 0
    np.testing.assert_array_equal(scribbled.state.positions, clean.state.positions)
    np.testing.assert_array_equal(scribbled.state.angular_velocities,
                                  clean.state.angular_velocities)


def test_the_2d_walk_refuses_an_array_it_cannot_rebuild():
    """law_loop.call_walk passes each array as its bare data: an array that is not
    C-contiguous, or not of the dtype the compiled walk reads, is refused when the
    caller compiles, with its name."""
    import numba
    from numba.core.errors import TypingError

    from graindyn.engines.soft.law_loop import call_walk

    @numba.njit
    def walk(positions, materials):
        n = positions.shape[0]
        f = np.zeros(n)
        call_walk(0, 0, n, 1e-7, f, np.zeros(1, np.uint8), np.zeros((1, 1, 1)), positions,
                  positions, positions, f, f, materials, np.zeros(n, np.int8),
                  np.zeros(3, np.int64), f[:3], np.zeros(n + 1, np.int64),
                  np.zeros(1, np.uint32), np.zeros(1, np.uint32), np.zeros((1, 1)),
                  np.zeros((1, 3)), np.zeros((n, 6)), np.zeros((1, 3)), f)

    positions = np.zeros((4, 3))
    with pytest.raises(TypingError, match="positions must be a C-contiguous array"):
        walk(np.asfortranarray(positions), np.zeros(4, np.int32))
    with pytest.raises(TypingError, match="materials must be a C-contiguous array of int32"):
        walk(positions, np.zeros(4, np.int64))
