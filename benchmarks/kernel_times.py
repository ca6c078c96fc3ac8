"""Where a step goes: each kernel of the compiled step timed alone on a benchmark bed.

    python benchmarks/kernel_times.py STATE CYL SIZE E e DT SKIN THREADS [REPS] [--cpu]
    python benchmarks/kernel_times.py RUN_DIR THREADS [REPS] [--cpu]
    python benchmarks/kernel_times.py silo2d THREADS [REPS] [--cpu]

Builds the bed of benchmarks/lammps_bed.py (same arguments), or the engine of a run
directory at its last checkpoint (any soft-engine run: its grains, walls, law and
integrator), or the 2000-disk bed of benchmarks/lammps_silo_2d.py (``silo2d``, its
linear law, in cell order as that benchmark runs it), runs 500 steps, then
times, each in a compiled loop of REPS calls (default 500, best of 5 batches), the
kernels of a step (engines/soft/loop.py): the half-skin test,
drift, pair forces, wall forces (and the sum onto walls), the gather-and-correct pass
(alone, and with the next step's drift), and a whole step (run_chunk: its integrator
may evaluate the forces more than once, as the optimized velocity Verlet does); for
``silo2d`` also the pair forces written out by hand (pair_bound_2d.py), with LAMMPS's
physics and with graindyn's, on the same lists and contacts.
Prints microseconds per call: of wall time, or with ``--cpu`` of this process's CPU
time (time.process_time: one thread on a machine other jobs share; with more threads
it adds theirs up).  The kernels run on the settled bed, restored before each batch
of calls.
"""
import math
import pathlib
import sys
import time

import numba
import numpy as np

import graindyn  # noqa: F401  (chooses numba's threading layer before threads start)

from lammps_bed import bed


def from_run(folder):
    """The engine of the run in ``folder`` at its last checkpoint."""
    from graindyn.config import load
    from graindyn.output.rundir import RunDirectory
    from graindyn.runner import restored

    folder = pathlib.Path(folder)
    return restored(RunDirectory(folder), load(folder / "config.toml"))[1]


def silo_bed():
    """The settled 2000-disk bed of lammps_silo_2d.py with its physics, in cell order."""
    import tempfile

    import lammps_silo_2d as silo

    work = pathlib.Path(tempfile.gettempdir()) / "graindyn_silo_bench"
    work.mkdir(parents=True, exist_ok=True)
    return silo.bed_simulation(silo.settled_bed(2000, work))


CLOCK = [time.perf_counter]


def main(argv):
    if "--cpu" in argv:
        argv = [a for a in argv if a != "--cpu"]
        CLOCK[0] = time.process_time
    if len(argv) in (2, 3) and argv[0] == "silo2d":
        threads = argv[1]
        reps = int(argv[2]) if len(argv) == 3 else 500
        numba.set_num_threads(int(threads))
        sim = silo_bed()
    elif len(argv) in (2, 3) and pathlib.Path(argv[0]).is_dir():
        threads = argv[1]
        reps = int(argv[2]) if len(argv) == 3 else 500
        numba.set_num_threads(int(threads))
        sim = from_run(argv[0])
    elif len(argv) in (8, 9):
        state_file, cyl, size, young, rest, dt, skin, threads = argv[:8]
        reps = int(argv[8]) if len(argv) == 9 else 500
        numba.set_num_threads(int(threads))
        sim = bed(state_file, cyl, size, young, rest, dt, skin)
    else:
        sys.exit(__doc__)
    from graindyn.engines.soft import loop
    from graindyn.engines.soft.contacts import PAIRS, PLANAR, WALLS, contact_forces
    from graindyn.engines.soft.integrators import before_force

    sim.run(steps=500)
    args = (sim.model_ids, sim.params, sim._law, sim.clock, sim._grains(), sim._walls(), sim._periodic(), sim.pairs, sim.counters,
            sim.integrator_history, sim.block_scratch, sim.images)

    @numba.njit(_nrt=False)   # as the time loop (_jit.driver): no reference counting
    def t_due(reps, model, params, law, clock, g, w, p, pairs, counters, history, scratch,
              images):
        s = 0
        for _ in range(reps):
            s += loop.rebuild_due(clock, w.offset, w.reference_offset, w.velocity)
        return s

    @numba.njit(_nrt=False)
    def t_drift(reps, model, params, law, clock, g, w, p, pairs, counters, history, scratch,
                images):
        for _ in range(reps):
            before_force(counters[loop.INTEGRATOR], np.int64(0), clock[loop.DT],
                         counters[loop.HISTORY_STEPS] > 0, counters[loop.DIM], g.positions, g.velocities,
                         g.angular_velocities, g.orientations, g.accelerations,
                         g.angular_accelerations, g.fixed, history)

    @numba.njit(_nrt=False)
    def t_part(reps, part, model, params, law, clock, g, w, p, pairs, counters, history,
               scratch, images):
        s = 0.0
        if counters[loop.DIM] == 2:
            part |= PLANAR
        for _ in range(reps):
            s += contact_forces(model, params, law, g.positions, g.velocities,
                                g.angular_velocities, g.radii, g.masses, g.materials, g.fixed,
                                p.flag, p.length, pairs.start, pairs.partners,
                                pairs.scratch_partners, pairs.history, pairs.force,
                                pairs.torque_j, w.kind, w.geometry, w.offset, w.velocity,
                                w.material, w.wall_start, w.wall_ids, w.scratch_wall_ids,
                                w.wall_history, w.contact_force, w.contact_torque, pairs.own,
                                g.max_overlap, clock[loop.DT], scratch.size, part)[0]
        return s

    @numba.njit(_nrt=False)
    def t_forces(reps, model, params, law, clock, g, w, p, pairs, counters, history, scratch,
                 images):
        s = 0.0
        for _ in range(reps):
            s += loop.evaluate_forces(model, params, law, g, pairs, w, p, images,
                                      clock[loop.GX:loop.GZ + 1], clock[loop.DT],
                                      scratch.size, counters[loop.DIM])[2]
        return s

    @numba.njit(_nrt=False)
    def t_correct(reps, drift_next, model, params, law, clock, g, w, p, pairs, counters,
                  history, scratch, images):
        s = 0.0
        for _ in range(reps):
            s += loop._after(counters[loop.INTEGRATOR], np.int64(0), clock[loop.DT], counters,
                             clock[loop.GX:loop.GZ + 1], g, pairs, p, history, scratch,
                             drift_next)
        return s

    def t_after(reps, *args):
        return t_correct(reps, False, *args)

    def t_fused(reps, *args):
        return t_correct(reps, True, *args)

    def t_pairs(reps, *args):
        return t_part(reps, np.int64(PAIRS), *args)

    def t_walls(reps, *args):
        return t_part(reps, np.int64(WALLS), *args)

    def t_step(reps, *args):
        sim.run(steps=reps)

    rows = [("whole step (run)", t_step), ("half-skin test", t_due), ("drift", t_drift),
            ("pair forces", t_pairs), ("wall forces", t_walls),
            ("all forces + wall sums", t_forces), ("gather + correct", t_after),
            ("gather + correct + drift", t_fused)]
    print(f"N {sim.state.n}  threads {threads}  listed pairs {int(sim.pairs.start[-1])}  "
          f"rebuilds {sim.rebuilds}")
    arrays = [a for a in _arrays(args) if a.flags.writeable]
    saved = [a.copy() for a in arrays]
    for name, fn in rows:
        for a, copy in zip(arrays, saved):    # each kernel starts from the settled bed
            np.copyto(a, copy)
        fn(2, *args)
        best = min(_timed(fn, reps, args, arrays, saved) for _ in range(5))
        print(f"{name:24s} {best * 1e6:9.2f} us")
    if argv[0] == "silo2d":
        for a, copy in zip(arrays, saved):     # the settled bed again
            np.copyto(a, copy)
        _bounds(sim, reps)


def _bounds(sim, reps):
    """The silo bed's pair forces written out by hand (pair_bound_2d.py), timed on the
    same lists and contact state: the physics of LAMMPS's law and of graindyn's."""
    import lammps_silo_2d as silo
    import pair_bound_2d as bound

    state = sim.state
    args = bound.loop_arguments(sim, silo.gamma_n(0.5 * float(state.masses.mean())))
    history = args[7]
    saved = history.copy()
    for name, loop in (("LAMMPS's physics", bound.lammps_physics),
                       ("graindyn's physics", bound.graindyn_physics)):
        loop(*args)

        @numba.njit
        def calls(reps, args):
            s = 0.0
            for _ in range(reps):
                s += loop(*args)
            return s
        best = math.inf
        for _ in range(5):
            np.copyto(history, saved)
            t0 = CLOCK[0]()
            calls(reps, args)
            best = min(best, (CLOCK[0]() - t0) / reps)
        print(f"pairs by hand, {name:18s} {best * 1e6:9.2f} us")


def _arrays(item):
    """The numpy arrays in a nest of tuples (the bundles are namedtuples)."""
    if isinstance(item, np.ndarray):
        return [item]
    if isinstance(item, tuple):
        return [a for sub in item for a in _arrays(sub)]
    return []


def _timed(fn, reps, args, arrays, saved):
    for a, copy in zip(arrays, saved):
        np.copyto(a, copy)
    clock = CLOCK[0]
    t0 = clock()
    fn(reps, *args)
    return (clock() - t0) / reps


if __name__ == "__main__":
    main(sys.argv[1:])
