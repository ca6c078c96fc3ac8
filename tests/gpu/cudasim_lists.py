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
        p, w = sim.pairs, sim.wall_pairs
        needed, wall_needed = rebuild(
            sim.state.positions, sim.state.radii, sim.clock[loop.SKIN], *sim._periodic(),
            *p[:8], sim.walls.kind, sim.walls.geometry, sim.walls.offset, *w[:6],
            sim.reference_positions, sim.reference_offset)
        if needed <= p[1].size and wall_needed <= w[1].size:
            return
        if needed > p[1].size:
            sim._allocate_pairs(int(1.3 * needed) + 64)
        if wall_needed > w[1].size:
            sim._allocate_walls(int(1.3 * wall_needed) + 16)


def lists(sim):
    p, w = sim.pairs, sim.wall_pairs
    m, mw = int(p[0][-1]), int(w[0][-1])
    return [p[0], p[1][:m], p[2][:m], p[6], p[7][:m], w[0], w[1][:mw], w[2][:mw],
            sim.state.positions, sim.reference_positions]


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
    grown = [int(cpu.pairs[1].size), int(gpu.pairs[1].size)]
    rng = np.random.default_rng(8)
    shift = rng.normal(scale=1e-4, size=(300, 3))
    for sim in (cpu, gpu):
        sim.state.positions[:] += shift
        m = int(sim.pairs[0][-1])
        sim.pairs[2][:m] = np.arange(m * sim.pairs[2].shape[1]).reshape(m, sim.pairs[2].shape[1])
        mw = int(sim.wall_pairs[0][-1])
        sim.wall_pairs[2][:mw] = -np.arange(mw * sim.wall_pairs[2].shape[1]).reshape(
            mw, sim.wall_pairs[2].shape[1])
    cpu_rebuild(cpu)
    device._upload()
    device._rebuild(np.ones(1, np.int64))
    device._download()
    second = compare(lists(cpu), lists(gpu))
    rng = np.random.default_rng(9)
    values = rng.integers(0, 5, 1000)
    a = cuda.to_device(values)
    device.lists.scan(a)
    print(json.dumps({"first": first, "second": second, "pairs": int(cpu.pairs[0][-1]),
                      "walls": int(cpu.wall_pairs[0][-1]), "capacity": grown,
                      "carried": int(np.count_nonzero(cpu.pairs[2][:int(cpu.pairs[0][-1])])),
                      "scan": bool(np.array_equal(a.copy_to_host(), np.cumsum(values)))}))


if __name__ == "__main__":
    main()
