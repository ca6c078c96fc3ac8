"""Array memory per grain of a large bed made by tiling a settled one.

    python benchmarks/memory_tiled.py STATE SIZE NX NY [OUT]
    NUMBA_ENABLE_CUDASIM=1 GRAINDYN_DEVICE_MEMORY=1 python benchmarks/memory_tiled.py ...

STATE: a settled bed (x y z r per line, SI) in the box [0, SIZE]^2 with an open top,
as written by ../shared/bench (state_settle_10000.txt has SIZE = 0.024).  The bed is
repeated NX x NY times in x and y inside one box, built with the LAMMPS-benchmark
physics (Hertz, Mindlin, Tsuji), and advanced a few steps; prints N, the array bytes
per grain (Simulation.memory_bytes), the peak RSS of the process, contacts and listed
pairs per grain.  OUT, if given, receives the tiled bed in the same format (for
benchmarks/lammps_bed.py).  With GRAINDYN_DEVICE_MEMORY=1 the run uses backend gpu
and also prints the bytes per grain the GPU engine allocates on the device
(DeviceEnsemble.memory_bytes; under the CUDA simulator this needs no GPU, the sizes
are the same).
"""
import os
import resource
import sys

import numpy as np


def tiled(state_file, size, nx, ny, backend="cpu", out=None):
    """The settled bed of ``state_file`` repeated nx x ny times in one box, its grains in
    cell order, with the LAMMPS-benchmark physics (Hertz, Mindlin, Tsuji; dt 2e-6 s): a
    Simulation."""
    import graindyn as gd

    bed = np.loadtxt(state_file, ndmin=2)
    positions = np.vstack([bed[:, :3] + [ix * size, iy * size, 0.0]
                           for ix in range(nx) for iy in range(ny)])
    radii = np.tile(bed[:, 3], nx * ny)
    if out is not None:
        np.savetxt(out, np.column_stack((positions, radii)))
    state = gd.State.create(positions, radii, 2650.0)
    # tile after tile, a grain's neighbours across a tile edge would lie far in index:
    # cell order, as lammps_bed.py loads its beds (cells of the neighbour cutoff)
    state = state.reordered(gd.cell_order(state.positions, 2.0 * radii.max() + 1e-4))
    grain = gd.Material("bed", density=2650.0, youngs_modulus=1e8, poisson_ratio=0.3,
                        restitution=0.9, friction_sliding=0.5, tangential_damping=1.0)
    walls = gd.box((0.0, 0.0, 0.0), (nx * size, ny * size, 10 * size))
    return gd.Simulation(state, [grain], gd.ContactModel("hertz", "tsuji", "mindlin",
                                                          limit_damping=False),
                         walls=walls, dt=2e-6, skin=1e-4, check_interval=1000,
                         backend=backend)


def main(argv):
    if len(argv) not in (4, 5):
        sys.exit(__doc__)
    state_file, size, nx, ny = argv[0], float(argv[1]), int(argv[2]), int(argv[3])
    device = os.environ.get("GRAINDYN_DEVICE_MEMORY") == "1"
    from graindyn.analysis.packing import coordination_number

    sim = tiled(state_file, size, nx, ny, "gpu" if device else "cpu",
                argv[4] if len(argv) == 5 else None)
    state = sim.state
    sim.run(steps=1 if device else 20)
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    print(f"N {state.n} array_bytes_per_grain {sim.memory_bytes() / state.n:.0f} "
          f"peak_rss_MB {rss / 1e6:.0f} contacts_per_grain {coordination_number(sim):.3f} "
          f"listed_pairs_per_grain {int(sim.pairs.start[-1]) / state.n:.3f}")
    if device:
        print(f"device_bytes_per_grain {sim._device.memory_bytes() / state.n:.0f}")


if __name__ == "__main__":
    main(sys.argv[1:])
