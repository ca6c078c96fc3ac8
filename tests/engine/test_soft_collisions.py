"""Collisions of the soft engine (Simulation.collisions, wall_collisions): a contact that
starts, overlap > 0 where the pair (or grain and wall) did not touch at the evaluation
before, counted in the compiled loop through each contact's touching mark
(contacts.touch).  Checked against counts known in advance: one head-on collision of
two grains, one wall collision per bounce of an elastic grain on a floor (the bounce
count of its drop height), none for a resting stack however long it rests and however
often its lists are rebuilt, the same counts after a snapshot and restore, and the same
count whatever the blocks of grains the pair loop is cut into."""
import math

import numpy as np
import pytest

import graindyn as gd
from graindyn.engines.soft import loop
from graindyn.engines.soft.contacts import PAIRS, contact_forces
from graindyn.engines.soft.law_loop import prepare, workspace

R = 1e-3                          # grain radius [m]
DENSITY = 2650.0                  # [kg/m^3]
G = 9.81                          # [m/s^2]

pytestmark = pytest.mark.usefixtures("one_thread")


def simulation(positions, velocities=None, walls=(), gravity=(0.0, 0.0, -G),
               restitution=None, friction=0.0, radii=R, **options):
    """Hertz grains of E = 1e7 Pa, nu = 0.3 (walls of the same material), undamped when
    ``restitution`` is None, else Tsuji's damping for it; Mindlin friction ``friction``
    (none at 0); ``options`` go to Simulation."""
    positions = np.asarray(positions, dtype=float)
    state = gd.State.create(positions, np.broadcast_to(radii, len(positions)), DENSITY,
                            velocities=velocities)
    material = gd.Material(youngs_modulus=1e7, poisson_ratio=0.3, restitution=restitution,
                           friction_sliding=friction, friction_static=friction)
    model = gd.ContactModel("hertz", "none" if restitution is None else "tsuji",
                            "mindlin" if friction else "none")
    return gd.Simulation(state, [material], model, walls=list(walls), gravity=gravity,
                         **options)


def floor():
    """The plane z = 0, grains above it."""
    return gd.Plane((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), name="floor")


@pytest.mark.parametrize("restitution", [None, 0.5], ids=["elastic", "damped"])
def test_head_on_pair_collides_once(restitution):
    """Two grains 1 mm apart closing at 1 m/s in free space meet once and fly apart: one
    collision, however many steps the contact lasts (and, damped, also through the end
    of the contact where the damping cancels the elastic force)."""
    sim = simulation([[0.0, 0.0, 0.0], [3 * R, 0.0, 0.0]],
                     velocities=[[0.5, 0.0, 0.0], [-0.5, 0.0, 0.0]], gravity=(0.0, 0.0, 0.0),
                     restitution=restitution)
    assert sim.collisions == 0
    sim.run(time=5e-3)                     # they meet at 1 ms, the contact lasts < 1 ms
    v = sim.state.velocities[:, 0]
    assert v[0] < 0.0 < v[1]               # apart again
    assert sim.collisions == 1 and sim.wall_collisions == 0


def test_elastic_bounces_count_one_wall_collision_each():
    """A grain dropped from h = 1 mm above an elastic floor first lands at
    t1 = sqrt(2 h / g) and then every 2 t1 (the flight of a rebound to the same
    height; the contact time, about 0.4 ms, is small beside 2 t1 = 29 ms): at mid
    flight after the b-th landing, t1 + (b - 1/2) 2 t1, the floor has seen b
    collisions."""
    h = 1e-3
    sim = simulation([[0.0, 0.0, R + h]], walls=[floor()])
    t1 = math.sqrt(2 * h / G)
    for bounces in range(1, 5):
        sim.run(time=t1 + (bounces - 0.5) * 2 * t1 - sim.time)
        assert sim.wall_collisions == math.floor((sim.time - t1) / (2 * t1)) + 1
    assert sim.wall_collisions == 4
    assert sim.collisions == 0


def test_resting_stack_is_not_counted_again():
    """Three grains stacked on a floor, damped (e = 0.3), settle: their landings count,
    then 2000 steps at rest with the neighbour lists rebuilt every 100 steps add none
    (each contact's mark travels with its history over the rebuilds)."""
    sim = simulation([[0.0, 0.0, R], [0.0, 0.0, 3 * R], [0.0, 0.0, 5 * R]], walls=[floor()],
                     restitution=0.3)
    sim.run(time=0.05)
    pairs, walls = sim.collisions, sim.wall_collisions
    assert pairs >= 2 and walls >= 1
    assert len(sim.contacts().i) == 2 and len(sim.wall_contacts().grain) == 1
    rebuilds = sim.rebuilds
    for _ in range(20):
        sim.counters[loop.FORCE_REBUILD] = 1
        sim.run(steps=100)
    assert sim.rebuilds == rebuilds + 20
    assert len(sim.contacts().i) == 2 and len(sim.wall_contacts().grain) == 1
    assert (sim.collisions, sim.wall_collisions) == (pairs, walls)


def gas():
    """24 frictional grains flying at about 0.3 m/s in a closed 12 mm box without
    gravity (e = 0.9): a dilute gas."""
    rng = np.random.default_rng(7)
    cells = np.stack(np.meshgrid(*[np.arange(3)] * 3, indexing="ij"), -1).reshape(-1, 3)[:24]
    positions = (cells + 0.5) * 4 * R + rng.uniform(-0.3, 0.3, (24, 3)) * R
    velocities = rng.normal(scale=0.3, size=(24, 3))
    return simulation(positions, velocities=velocities, gravity=(0.0, 0.0, 0.0),
                      walls=gd.box((0.0, 0.0, 0.0), (12 * R, 12 * R, 12 * R),
                                   open_top=False),
                      restitution=0.9, friction=0.3)


def test_snapshot_restore_resumes_the_counts():
    """A gas run 3000 steps, snapshot taken after 1500: the restored copy ends with the
    same counts as the uninterrupted run, and so does one restored from a snapshot
    written before collisions were counted (no counters, no touching marks: the marks
    are set from the contact forces, the counts start from zero)."""
    sim = gas()
    sim.run(steps=1500)
    saved = sim.snapshot()
    at_snapshot = (sim.collisions, sim.wall_collisions)
    sim.run(steps=1500)
    final = (sim.collisions, sim.wall_collisions)
    assert final[0] > at_snapshot[0] > 0 and final[1] > at_snapshot[1] > 0

    resumed = gas()
    resumed.restore(saved)
    assert (resumed.collisions, resumed.wall_collisions) == at_snapshot
    resumed.run(steps=1500)
    assert (resumed.collisions, resumed.wall_collisions) == final
    np.testing.assert_array_equal(resumed.state.positions, sim.state.positions)

    old = dict(saved)
    old["loop/counters"] = saved["loop/counters"][:11]
    for group in ("pairs", "wall_contacts"):
        old[f"{group}/history"] = saved[f"{group}/history"][:, :-1]
    legacy = gas()
    legacy.restore(old)
    legacy.run(steps=1500)
    assert (legacy.collisions, legacy.wall_collisions) == \
        (final[0] - at_snapshot[0], final[1] - at_snapshot[1])


def test_count_is_the_same_by_blocks():
    """A dense bed whose marks are cleared: one pair evaluation counts every touching
    pair once, cut into one block or three (the parallel path, summed by block), and a
    second evaluation counts none."""
    rng = np.random.default_rng(3)
    n = 300
    sim = simulation(rng.uniform(0.0, 6e-3, (n, 3)), radii=rng.uniform(0.4e-3, 0.7e-3, n),
                     gravity=(0.0, 0.0, 0.0), dt=1e-7, allow_large_dt=True,
                     overlap_limit=10.0)
    sim.run(steps=1)
    touching = len(sim.contacts().i)
    assert touching > 300
    g, w, p, per = sim._grains(), sim._walls(), sim.pairs, sim._periodic()
    for nblock in (1, 3):
        p.history[:, -1] = 0.0
        law = prepare(workspace(sim._law.address, nblock, sim.history_size,
                                sim._law.planar), sim.params, p.partners.size)
        counts = []
        for _ in range(2):
            counts.append(contact_forces(
                sim.model_ids, sim.params, law, g.positions, g.velocities,
                g.angular_velocities, g.radii, g.masses, g.materials, g.fixed, per.flag,
                per.length, p.start, p.partners, p.scratch_partners, p.history, p.force,
                p.torque_j, w.kind, w.geometry, w.offset, w.velocity, w.material,
                w.wall_start, w.wall_ids, w.scratch_wall_ids, w.wall_history,
                w.contact_force, w.contact_torque, p.own, g.max_overlap, 1e-7, nblock,
                np.int64(PAIRS))[2])
        assert counts == [touching, 0], nblock


def touching_sets(sim):
    """The touching grain pairs (i, j), i < j, and (grain, wall) of the positions as they
    are: overlap > 0, as the pair loop and the wall loop test it."""
    s = sim.state
    x = s.positions
    i, j = np.triu_indices(s.n, 1)
    gap = np.sum((x[i] - x[j]) ** 2, axis=1) < (s.radii[i] + s.radii[j]) ** 2
    pairs = set(zip(i[gap].tolist(), j[gap].tolist()))
    walls = set()
    for w in range(len(sim.walls.kind)):
        distance, _ = sim.walls.distances(x, np.full(s.n, w))
        walls |= {(g, w) for g in np.flatnonzero(s.radii - distance > 0.0).tolist()}
    return pairs, walls


def test_counts_equal_the_contacts_that_start_step_by_step():
    """40 damped grains poured into a box, velocity Verlet (one force evaluation a step,
    at the positions the step ends at): over 600 steps the counts equal the contacts
    found touching after a step and not after the one before, counted here from the
    positions, grain pairs and grain-wall contacts apart; the contacts of the first
    evaluation, before any step, are not collisions."""
    rng = np.random.default_rng(11)
    cells = np.stack(np.meshgrid(*[np.arange(4)] * 2, np.arange(3), indexing="ij"),
                     -1).reshape(-1, 3)[:40]
    positions = (cells + 0.5) * 2.05 * R + rng.uniform(-0.1, 0.1, (40, 3)) * R
    sim = simulation(positions, velocities=rng.normal(scale=0.2, size=(40, 3)),
                     walls=gd.box((0.0, 0.0, 0.0), (8.2 * R, 8.2 * R, 20 * R)),
                     restitution=0.5, dt=2e-6)
    before = touching_sets(sim)
    expected = [0, 0]
    for _ in range(600):
        sim.run(steps=1)
        now = touching_sets(sim)
        for kind in (0, 1):
            expected[kind] += len(now[kind] - before[kind])
        before = now
    assert expected[0] > 20 and expected[1] > 20
    assert [sim.collisions, sim.wall_collisions] == expected
