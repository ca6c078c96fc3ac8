"""The soft-particle step on the GPU (issue 6): the step of core/loop.run_chunk, one
CUDA thread per grain, built from the CPU's own per-grain functions
(contacts.pair_row and wall_row, integrators.passes.drift_grain and correct_grain,
walls.walls_advance) through device.device_function.

``Simulation(..., backend="gpu")`` runs its chunks here: the arrays go to the device at
the start of a chunk and come back at its end, so everything between chunks (triggers,
outputs, protocols, checkpoints) sees the same host arrays as on the CPU, and a
checkpoint written on one backend resumes on the other.  Within a chunk:
* forces, contact histories, walls and the integrator advance on the device;
* the neighbour lists are built on the device (gpu/neighbours.py) when the half-skin
  rule, evaluated on the device, asks for it; the host reads that flag back each step,
  and the list sizes at each rebuild;
* wall totals, energies, the displacement bound and the checks of run_chunk (non-finite
  values, overlap, stop condition, every check_interval steps) are device reductions
  (gpu/reductions.py).
"""
import math

import numpy as np
from numba import cuda, float64

from ..core import loop
from ..core.contacts import pair_row, wall_row
from ..core.integrators import STAGES
from ..core.integrators.passes import correct_grain, drift_grain
from ..core.walls import walls_advance
from .device import device_function
from .neighbours import DeviceNeighbours
from .reductions import (BAD, CHECK_OPS, CHUNK, KINETIC, MAX, OVERLAP, POTENTIAL, SPEED2,
                         SUM, fold, ops_array, rows)
from .reductions import kernels as reduction_kernels

# threads per block of the per-grain kernels: one block per row of the reductions
THREADS = CHUNK
_KERNELS = {}


def kernels():
    """The CUDA kernels (compiled on first use, once per process)."""
    if _KERNELS:
        return _KERNELS
    drift = device_function(drift_grain)
    pair = device_function(pair_row)
    wall = device_function(wall_row)
    correct = device_function(correct_grain)
    advance = device_function(walls_advance)
    due = device_function(loop.rebuild_due)

    @cuda.jit(device=True)
    def block_rows(buf, values, row, ops):
        """Reduce buf[t, q] over the threads of the block (SUM or MAX by ops[q], a fixed
        tree) into row[q]; every thread of the block must call it."""
        t = cuda.threadIdx.x
        width = cuda.blockDim.x
        cuda.syncthreads()
        step = 1
        while step < width:
            step *= 2
        step //= 2
        while step > 0:
            if t < step and t + step < width:
                for q in range(values):
                    if ops[q] == SUM:
                        buf[t, q] += buf[t + step, q]
                    else:
                        buf[t, q] = max(buf[t, q], buf[t + step, q])
            cuda.syncthreads()
            step //= 2
        if t == 0:
            for q in range(values):
                row[q] = buf[0, q]

    @cuda.jit
    def drift_kernel(integrator, stage, dt, started, positions, velocities,
                     angular_velocities, orientations, accelerations, angular_accelerations,
                     fixed, history):
        i = cuda.grid(1)
        if i < positions.shape[0]:
            drift(i, integrator, stage, dt, started, positions, velocities,
                  angular_velocities, orientations, accelerations, angular_accelerations,
                  fixed, history)

    @cuda.jit
    def walls_kernel(motion_kind, motion, base, offset, velocity, force, clock, dt):
        if cuda.grid(1) == 0:
            advance(motion_kind, motion, base, offset, velocity, force, clock[loop.TIME], dt)

    @cuda.jit
    def force_kernel(model, params, positions, velocities, angular_velocities, radii, masses,
                     materials, fixed, periodic_flag, periodic_length, start, partners,
                     history, pair_force, own, pair_torque_j, kind, geometry, offset,
                     velocity, material, wall_start, wall_ids, wall_history, wall_force,
                     wall_torque, max_overlap, lost, ops, dt):
        """Contact forces of grain i; the energy its contacts dissipate, summed over the
        block into lost[block] (normal, tangential) [J]."""
        buf = cuda.shared.array((THREADS, 2), float64)
        i = cuda.grid(1)
        t = cuda.threadIdx.x
        buf[t, 0] = 0.0
        buf[t, 1] = 0.0
        if i < positions.shape[0]:
            dn, dt_ = pair(i, model, params, positions, velocities, angular_velocities, radii,
                           masses, materials, fixed, periodic_flag, periodic_length, start,
                           partners, history, pair_force, own, pair_torque_j, max_overlap,
                           dt)
            wn, wt = wall(i, model, params, positions, velocities, angular_velocities, radii,
                          masses, materials, kind, geometry, offset, velocity, material,
                          wall_start, wall_ids, wall_history, wall_force, wall_torque,
                          max_overlap, dt)
            buf[t, 0] = dn + wn
            buf[t, 1] = dt_ + wt
        block_rows(buf, 2, lost[cuda.blockIdx.x], ops)

    @cuda.jit
    def correct_kernel(integrator, stage, dt, started, dim, gravity, own, reverse_start,
                       reverse_pairs, pair_force, pair_torque_j, wall_start, wall_force,
                       wall_torque, forces, torques, masses, inertias, positions,
                       reference_positions, velocities, angular_velocities, orientations,
                       accelerations, angular_accelerations, fixed, periodic_flag,
                       periodic_length, history, bound, ops):
        """Gather and correct grain i; the largest squared displacement since the last
        build, speed and acceleration of the block go to bound[block]."""
        buf = cuda.shared.array((THREADS, 3), float64)
        i = cuda.grid(1)
        t = cuda.threadIdx.x
        buf[t, 0] = 0.0
        buf[t, 1] = 0.0
        buf[t, 2] = 0.0
        if i < positions.shape[0]:
            buf[t, 0], buf[t, 1], buf[t, 2] = correct(
                i, integrator, stage, dt, started, dim, gravity, own, reverse_start,
                reverse_pairs, pair_force, pair_torque_j, wall_start, wall_force,
                wall_torque, forces, torques, masses, inertias, positions,
                reference_positions, velocities, angular_velocities, orientations,
                accelerations, angular_accelerations, fixed, periodic_flag, periodic_length,
                history)
        block_rows(buf, 3, bound[cuda.blockIdx.x], ops)

    @cuda.jit
    def decide_kernel(clock, offset, reference_offset, velocity, control):
        """control[0] = 1 when the lists must be rebuilt before this step
        (core/loop.rebuild_due, one thread)."""
        if cuda.grid(1) == 0:
            control[0] = 1 if due(clock, offset, reference_offset, velocity) else 0

    @cuda.jit
    def tick_kernel(clock):
        if cuda.grid(1) == 0:
            clock[loop.TIME] += clock[loop.DT]

    _KERNELS.update(drift=drift_kernel, walls=walls_kernel, force=force_kernel,
                    correct=correct_kernel, decide=decide_kernel, tick=tick_kernel)
    return _KERNELS


class DeviceSimulation:
    """The device side of a Simulation with backend "gpu": ``chunk(nsteps)`` is
    core/loop.run_chunk on the GPU, with the same return values.  Same integrators, laws
    and walls as the CPU; results agree with it to floating-point reordering (fused
    multiply-adds on the device, sums of energies in another association)."""

    def __init__(self, sim):
        self.sim = sim
        self.k = dict(kernels(), **reduction_kernels())
        self.lists = None

    def _bundles(self):
        """The host arrays, in the order the device copies keep them."""
        s = self.sim
        return {"grains": list(s._grains()), "pairs": list(s.pairs),
                "walls": list(s._walls()), "periodic": list(s._periodic()),
                "loop": [s.clock, s.integrator_history]}

    def _upload(self):
        self.host = self._bundles()
        self.dev = {k: [cuda.to_device(a) for a in v] for k, v in self.host.items()}
        sim, n = self.sim, self.sim.state.n
        self.lost = cuda.device_array((rows(n), 2))
        self.model = cuda.to_device(sim.model_ids)
        self.params = cuda.to_device(sim.params)
        self.gravity = cuda.to_device(sim.clock[loop.GX:loop.GZ + 1].copy())
        self.control = cuda.to_device(np.zeros(1, np.int64))
        self.totals = cuda.device_array((rows(n), 3 * sim.walls.kind.size + 3))
        self.partial = cuda.device_array((rows(n), 6))
        self.checked = cuda.device_array(6)
        self.folded = cuda.device_array(max(6, self.totals.shape[1]))
        self.ops = {"totals": ops_array([SUM] * self.totals.shape[1]),
                    "lost": ops_array([SUM] * 2), "bound": ops_array([MAX] * 3),
                    "checks": ops_array(CHECK_OPS)}
        if self.lists is None or self.lists.n != n:
            self.lists = DeviceNeighbours(n)

    def memory_bytes(self):
        """Bytes of every array this engine keeps on the device (after a chunk or an
        upload): the simulation's arrays, the neighbour-build scratch and the reduction
        rows.  The CUDA context and numba's own allocations are not counted."""
        arrays = [a for bundle in self.dev.values() for a in bundle]
        arrays += [self.lost, self.model, self.params, self.gravity,
                   self.control, self.totals, self.partial, self.checked, self.folded,
                   *self.ops.values()]
        return sum(a.nbytes for a in arrays) + self.lists.memory_bytes()

    def _download(self):
        for k in self.dev:
            for dev, host in zip(self.dev[k], self.host[k]):
                dev.copy_to_host(host)

    def _rebuild(self):
        """Device-side neighbour build (gpu/neighbours.py); the new lists, written in the
        scratch arrays, are swapped in.  When a list outgrows its arrays, they are grown
        on the host as the CPU loop does (the old lists kept) and the build runs again.
        Returns False (nothing rebuilt) when a position is not finite."""
        sim = self.sim
        skin = float(sim.clock[loop.SKIN])
        cutoff = 2.0 * float(sim.state.radii.max()) + skin
        while True:
            p, w = self.dev["pairs"], self.dev["walls"]
            needed, wall_needed, finite = self.lists.build(
                cutoff, skin, self.dev["grains"], p, w, self.dev["periodic"])
            if not finite:
                return False
            if needed <= p[1].size and wall_needed <= w[11].size:
                break
            self._download()
            if needed > p[1].size:
                sim._allocate_pairs(int(1.3 * needed) + 64)
            if wall_needed > w[11].size:
                sim._allocate_walls(int(1.3 * wall_needed) + 16)
            self._upload()
        for a, b in ((0, 3), (1, 4), (2, 5)):
            p[a], p[b] = p[b], p[a]
            w[10 + a], w[13 + a] = w[13 + a], w[10 + a]
        sim.counters[loop.REBUILDS] += 1
        return True

    def _launch(self, name, n, *args):
        """One thread per item; blocks of THREADS threads, or one block of n < THREADS
        (a few grains, a single-thread reduction)."""
        threads = max(1, min(THREADS, n))
        self.k[name][(n + threads - 1) // threads, threads](*args)

    def _evaluate(self, share):
        g, p, w, per = (self.dev[k] for k in ("grains", "pairs", "walls", "periodic"))
        n = self.sim.state.n
        self._launch("force", n, self.model, self.params, g[0], g[1], g[2], g[8],
                     g[9], g[11], g[12], per[0], per[2], p[0], p[1], p[2], p[8], p[9], p[10],
                     w[0], w[1], w[5], w[6], w[7], w[10], w[11], w[12], w[16], w[17], g[14],
                     self.lost, self.ops["lost"], share)
        self._launch("totals_partial", rows(n), w[10], w[11], w[16], w[6], self.lost,
                     self.totals)
        fold(self.k, self.totals, self.ops["totals"], self.folded)
        self._launch("totals_apply", 1, self.folded, w[8], self.dev["loop"][0], share)

    def _correct(self, stage, dt):
        sim = self.sim
        g, p, w, per = (self.dev[k] for k in ("grains", "pairs", "walls", "periodic"))
        integrator = int(sim.counters[loop.INTEGRATOR])
        self._launch("correct", sim.state.n, integrator, stage, dt,
                     sim.counters[loop.HISTORY_STEPS] > 0, int(sim.counters[loop.DIM]),
                     self.gravity, p[9], p[6], p[7], p[8], p[10], w[10], w[16], w[17], g[4], g[5],
                     g[9], g[10], g[0], g[13], g[1], g[2], g[3], g[6], g[7], g[12], per[0],
                     per[2], self.dev["loop"][1], self.partial, self.ops["bound"])
        fold(self.k, self.partial[:, :3], self.ops["bound"], self.folded)
        self._launch("bound_apply", 1, self.folded, dt, self.dev["loop"][0])

    def _check(self, reset):
        """The reductions of core/loop._checks: array indexed by reductions.BAD ...
        POTENTIAL; max_overlap is set back to zero when ``reset``."""
        g = self.dev["grains"]
        n = self.sim.state.n
        self._launch("checks_partial", rows(n), g[0], g[1], g[2], g[4], g[9], g[10], g[12],
                     g[14], self.gravity, reset, self.partial)
        fold(self.k, self.partial[:, :POTENTIAL], self.ops["checks"], self.checked)
        self._launch("potential_partial", rows(n), g[0], g[9], g[12], self.gravity,
                     self.checked, self.partial)
        fold(self.k, self.partial[:, POTENTIAL:], self.ops["checks"][POTENTIAL:],
             self.checked[POTENTIAL:])
        return self.checked.copy_to_host()

    def _status(self):
        """core/loop._checks on the device results: a run_chunk status code."""
        sim = self.sim
        out = self._check(True)
        if out[BAD] != 0.0:
            return loop.NAN
        if out[OVERLAP] > sim.clock[loop.OVERLAP_LIMIT]:
            return loop.OVERLAP
        kind, value = sim.counters[loop.COND_KIND], sim.clock[loop.COND_VALUE]
        if kind == loop.MAX_SPEED_BELOW and math.sqrt(out[SPEED2]) < value:
            return loop.CONDITION
        if kind == loop.ENERGY_RATIO_BELOW and out[KINETIC] <= value * out[POTENTIAL]:
            return loop.CONDITION
        return loop.DONE

    def chunk(self, nsteps):
        """Up to ``nsteps`` steps on the device: (status, steps done), as run_chunk
        (GROW never comes back: the lists are grown here)."""
        sim = self.sim
        self._upload()
        try:
            return self._steps(nsteps)
        finally:
            self._download()
            sim.state.time = sim.time
            sim.state.step = sim.step

    def _steps(self, nsteps):
        sim = self.sim
        counters = sim.counters
        dt = float(sim.clock[loop.DT])
        integrator = int(counters[loop.INTEGRATOR])
        for s in range(nsteps):
            w = self.dev["walls"]
            if counters[loop.FORCE_REBUILD] == 0:
                self._launch("decide", 1, self.dev["loop"][0], w[5], w[9], w[6], self.control)
            if counters[loop.FORCE_REBUILD] != 0 or self.control.copy_to_host()[0]:
                if not self._rebuild():
                    return loop.NAN, s
                counters[loop.FORCE_REBUILD] = 0
            g, w, clock = self.dev["grains"], self.dev["walls"], self.dev["loop"][0]
            if counters[loop.PRIMED] == 0:
                self._evaluate(0.0)
                self._correct(0, 0.0)
                counters[loop.PRIMED] = 1
                # grains that start too deep in each other or in a wall: stop before moving
                if self._check(False)[OVERLAP] > sim.clock[loop.OVERLAP_LIMIT]:
                    return loop.OVERLAP, s
            for stage in range(STAGES[integrator]):
                self._launch("drift", sim.state.n, integrator, stage, dt,
                             counters[loop.HISTORY_STEPS] > 0, g[0], g[1], g[2], g[3], g[6],
                             g[7], g[12], self.dev["loop"][1])
                if stage == 0:
                    self._launch("walls", 1, w[2], w[3], w[4], w[5], w[6], w[8], clock, dt)
                self._evaluate(dt / STAGES[integrator])
                self._correct(stage, dt)
            self._launch("tick", 1, clock)
            counters[loop.STEP] += 1
            counters[loop.HISTORY_STEPS] += 1
            if counters[loop.STEP] % counters[loop.CHECK_INTERVAL] == 0 or s == nsteps - 1:
                status = self._status()
                if status != loop.DONE:
                    return status, s + 1
        return loop.DONE, nsteps
