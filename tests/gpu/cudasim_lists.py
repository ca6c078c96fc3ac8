"""Run by tests/gpu/test_cudasim.py under NUMBA_ENABLE_CUDASIM=1: neighbour lists built
by the device kernels (engines/soft/gpu/neighbours.py) against core/neighbors.rebuild on a
polydisperse bed, periodic in x and y, walls in z, more grains than a thread block;
then every grain moved and each listed pair given a history, and both rebuilt again
(history carried over).  Also the device prefix sum over several blocks.
Prints one JSON line."""
import json

import numpy as np
from numba import cuda

import graindyn as gd
from graindyn.engines.soft import loop
from graindyn.core.neighbors import rebuild
from graindyn.engines.soft.gpu.engine import DeviceEnsemble


def make():
    rng = np.random.default_rng(7)
    n = 300
    box = np.array([6e-3, 6e-3, 8e-3])
    pos = rng.uniform(0.0, 1.0, (n, 3)) * box
    pos[:, 2] = np.clip(pos[:, 2], 0.5e-3, 7.5e-3)
    state = gd.State.create(pos, rng.uniform(0.3e-3, 0.6e-3, n), 2650.0)
    walls = [gd.Plane((0, 0, 0), (0, 0, 1)), gd.Plane((0, 0, 8e-3), (0, 0, -1))]
    return gd.Simulation(state, [gd.Material(youngs_modulus=1e7)], walls=walls,
                         periodic=[gd.PeriodicBoundary(0, 0.0, 6e-3),
                                   gd.PeriodicBoundary(1, 0.0, 6e-3)], dt=1e-7,
                         skin=2e-4)


def cpu_rebuild(sim):
    while True:
        p, w, per = sim.pairs, sim.wall_pairs, sim._periodic()
        needed, wall_needed = rebuild(
            sim.state.positions, sim.state.radii, sim.clock[loop.SKIN], per.flag, per.lo,
            per.length, p.start, p.partners, p.history, p.scratch_start, p.scratch_partners,
            p.scratch_history, p.reverse_start, p.reverse_pairs, sim.walls.kind,
            sim.walls.geometry, sim.walls.offset, w.start, w.ids, w.history, w.scratch_start,
            w.scratch_ids, w.scratch_history, sim.reference_positions, sim.reference_offset)
        if needed <= p.partners.size and wall_needed <= w.ids.size:
            return
        if needed > p.partners.size:
            sim._allocate_pairs(int(1.3 * needed) + 64)
        if wall_needed > w.ids.size:
            sim._allocate_walls(int(1.3 * wall_needed) + 16)


def lists(sim):
    p, w = sim.pairs, sim.wall_pairs
    m, mw = int(p.start[-1]), int(w.start[-1])
    return [p.start, p.partners[:m], p.history[:m], p.reverse_start, p.reverse_pairs[:m],
            w.start, w.ids[:mw], w.history[:mw], sim.state.positions, sim.reference_positions]


def compare(a, b):
    return [bool(x.shape == y.shape and np.array_equal(x, y)) for x, y in zip(a, b)]


def main():
    cpu, gpu = make(), make()
    device = DeviceEnsemble([gpu])
    device._upload()
    cpu_rebuild(cpu)
    device._rebuild(np.ones(1, np.int64))
    device._download()
    first = compare(lists(cpu), lists(gpu))
    grown = [int(cpu.pairs.partners.size), int(gpu.pairs.partners.size)]
    rng = np.random.default_rng(8)
    shift = rng.normal(scale=1e-4, size=(300, 3))
    for sim in (cpu, gpu):
        sim.state.positions[:] += shift
        history, wall_history = sim.pairs.history, sim.wall_pairs.history
        m = int(sim.pairs.start[-1])
        history[:m] = np.arange(m * history.shape[1]).reshape(m, history.shape[1])
        mw = int(sim.wall_pairs.start[-1])
        wall_history[:mw] = -np.arange(mw * wall_history.shape[1]).reshape(
            mw, wall_history.shape[1])
    cpu_rebuild(cpu)
    device._upload()
    device._rebuild(np.ones(1, np.int64))
    device._download()
    second = compare(lists(cpu), lists(gpu))
    rng = np.random.default_rng(9)
    values = rng.integers(0, 5, 1000)
    a = cuda.to_device(values)
    device.lists.scan(a)
    m = int(cpu.pairs.start[-1])
    print(json.dumps({"first": first, "second": second, "pairs": m,
                      "walls": int(cpu.wall_pairs.start[-1]), "capacity": grown,
                      "carried": int(np.count_nonzero(cpu.pairs.history[:m])),
                      "scan": bool(np.array_equal(a.copy_to_host(), np.cumsum(values)))}))


if __name__ == "__main__":
    main()
