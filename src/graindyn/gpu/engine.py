"""The soft-particle step on the GPU, first part (issue 6): the same step as
core/loop.run_chunk, one CUDA thread per grain, built from the CPU's own per-grain
functions (contacts.pair_row and wall_row, integrators.passes.drift_grain and
correct_grain, walls.walls_advance) through device.device_function.

What this part does and does not do yet:
* all grain, contact and wall arrays live on the device between steps; forces,
  contact histories, walls and the integrator advance there;
* the neighbour lists are built on the device (gpu/neighbours.py) when the half-skin
  rule, evaluated on the device, asks for it; the host reads that one flag back per
  step, and the list sizes at each rebuild;
* the energy sums and wall totals run on one device thread in grain order (exact, but
  serial); the NaN/overlap/stop-condition checks of run_chunk are not done here.
"""
import math

import numpy as np
from numba import cuda

from ..core import loop
from ..core.contacts import pair_row, wall_row
from ..core.integrators import STAGES
from ..core.integrators.passes import correct_grain, drift_grain
from ..core.walls import walls_advance
from .device import device_function
from .neighbours import DeviceNeighbours

THREADS = 128          # threads per block of the per-grain kernels
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
                     wall_torque, max_overlap, dissipation, dt):
        i = cuda.grid(1)
        if i < positions.shape[0]:
            dn, dt_ = pair(i, model, params, positions, velocities, angular_velocities, radii,
                           masses, materials, fixed, periodic_flag, periodic_length, start,
                           partners, history, pair_force, own, pair_torque_j, max_overlap,
                           dt)
            wn, wt = wall(i, model, params, positions, velocities, angular_velocities, radii,
                          masses, materials, kind, geometry, offset, velocity, material,
                          wall_start, wall_ids, wall_history, wall_force, wall_torque,
                          max_overlap, dt)
            dissipation[i, 0] = dn + wn
            dissipation[i, 1] = dt_ + wt

    @cuda.jit
    def totals_kernel(wall_start, wall_ids, contact_force, velocity, force, dissipation,
                      clock, share):
        """Force on each wall, wall power and energies, in grain order (one thread)."""
        if cuda.grid(1) != 0:
            return
        for w in range(force.shape[0]):
            for d in range(3):
                force[w, d] = 0.0
        power = 0.0
        lost_n = 0.0
        lost_t = 0.0
        for i in range(dissipation.shape[0]):
            lost_n += dissipation[i, 0]
            lost_t += dissipation[i, 1]
            for q in range(wall_start[i], wall_start[i + 1]):
                w = wall_ids[q]
                for d in range(3):
                    force[w, d] -= contact_force[q, d]
                    power += contact_force[q, d] * velocity[w, d]
        clock[loop.DISS_N] += lost_n
        clock[loop.DISS_T] += lost_t
        clock[loop.WALL_WORK] += power * share

    @cuda.jit
    def correct_kernel(integrator, stage, dt, started, dim, gravity, own, reverse_start,
                       reverse_pairs, pair_force, pair_torque_j, wall_start, wall_force,
                       wall_torque, forces, torques, masses, inertias, positions,
                       reference_positions, velocities, angular_velocities, orientations,
                       accelerations, angular_accelerations, fixed, periodic_flag,
                       periodic_length, history, squares):
        i = cuda.grid(1)
        if i < positions.shape[0]:
            squares[i, 0], squares[i, 1], squares[i, 2] = correct(
                i, integrator, stage, dt, started, dim, gravity, own, reverse_start,
                reverse_pairs, pair_force, pair_torque_j, wall_start, wall_force,
                wall_torque, forces, torques, masses, inertias, positions,
                reference_positions, velocities, angular_velocities, orientations,
                accelerations, angular_accelerations, fixed, periodic_flag, periodic_length,
                history)

    @cuda.jit
    def bound_kernel(squares, dt, clock):
        """clock[MOVE] = max |r - r_ref| + max |v| dt + max |a| dt^2/2 (one thread)."""
        if cuda.grid(1) != 0:
            return
        d2 = v2 = a2 = 0.0
        for i in range(squares.shape[0]):
            d2 = max(d2, squares[i, 0])
            v2 = max(v2, squares[i, 1])
            a2 = max(a2, squares[i, 2])
        clock[loop.MOVE] = math.sqrt(d2) + math.sqrt(v2) * dt + 0.5 * math.sqrt(a2) * dt * dt

    @cuda.jit
    def decide_kernel(clock, offset, reference_offset, velocity, control):
        """control[0] = 1 when the lists must be rebuilt before this step: the half-skin
        rule of core/loop.run_chunk (one thread)."""
        if cuda.grid(1) != 0:
            return
        dt = clock[loop.DT]
        wall_move = 0.0
        for w in range(offset.shape[0]):
            d2 = 0.0
            v2 = 0.0
            for d in range(3):
                d2 += (offset[w, d] - reference_offset[w, d]) ** 2
                v2 += velocity[w, d] ** 2
            wall_move = max(wall_move, math.sqrt(d2) + 2.0 * math.sqrt(v2) * dt)
        grain_move = clock[loop.MOVE]
        control[0] = 1 if grain_move + max(grain_move, wall_move) > clock[loop.SKIN] else 0

    @cuda.jit
    def tick_kernel(clock):
        if cuda.grid(1) == 0:
            clock[loop.TIME] += clock[loop.DT]

    _KERNELS.update(drift=drift_kernel, walls=walls_kernel, force=force_kernel,
                    totals=totals_kernel, correct=correct_kernel, bound=bound_kernel,
                    decide=decide_kernel, tick=tick_kernel)
    return _KERNELS


class DeviceSimulation:
    """A Simulation advanced on the GPU: ``DeviceSimulation(sim).run(steps)`` moves the
    simulation's arrays to the device, runs the steps there and copies everything back
    into ``sim`` (so its state, contacts, walls, energies and snapshot are those of the
    GPU run).  Same integrators, laws and walls as the CPU; results agree with it to
    floating-point reordering (fused multiply-adds on the device)."""

    def __init__(self, sim):
        self.sim = sim
        self.k = kernels()

    def _bundles(self):
        """The host arrays, in the order the device copies keep them."""
        s = self.sim
        return {"grains": list(s._grains()), "pairs": list(s.pairs),
                "walls": list(s._walls()), "periodic": list(s._periodic()),
                "loop": [s.clock, s.integrator_history]}

    def _upload(self):
        self.host = self._bundles()
        self.dev = {k: [cuda.to_device(a) for a in v] for k, v in self.host.items()}
        n = self.sim.state.n
        self.dissipation = cuda.device_array((n, 2))
        self.squares = cuda.device_array((n, 3))
        self.model = cuda.to_device(self.sim.model_ids)
        self.params = cuda.to_device(self.sim.params)
        self.gravity = cuda.to_device(self.sim.clock[loop.GX:loop.GZ + 1].copy())
        self.control = cuda.to_device(np.zeros(1, np.int64))
        if getattr(self, "lists", None) is None or self.lists.n != n:
            self.lists = DeviceNeighbours(n)

    def _download(self, groups=None):
        for k in groups or self.dev:
            for dev, host in zip(self.dev[k], self.host[k]):
                dev.copy_to_host(host)

    def _rebuild(self):
        """Device-side neighbour build (gpu/neighbours.py); the new lists, written in the
        scratch arrays, are swapped in.  When a list outgrows its arrays, they are grown
        on the host as the CPU loop does (the old lists kept) and the build runs again."""
        sim = self.sim
        cutoff = 2.0 * float(sim.state.radii.max()) + float(sim.clock[loop.SKIN])
        while True:
            p, w = self.dev["pairs"], self.dev["walls"]
            needed, wall_needed, finite = self.lists.build(
                cutoff, float(sim.clock[loop.SKIN]), self.dev["grains"], p, w,
                self.dev["periodic"])
            if not finite:
                raise FloatingPointError("a grain position is not finite: the run blew up "
                                         f"before step {sim.step + 1}")
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

    def _launch(self, name, n, *args):
        blocks = max(1, (n + THREADS - 1) // THREADS)
        self.k[name][blocks, THREADS](*args)

    def _evaluate(self, share):
        g, p, w, per = (self.dev[k] for k in ("grains", "pairs", "walls", "periodic"))
        n = self.sim.state.n
        self._launch("force", n, self.model, self.params, g[0], g[1], g[2], g[8],
                     g[9], g[11], g[12], per[0], per[2], p[0], p[1], p[2], p[8], p[9], p[10],
                     w[0], w[1], w[5], w[6], w[7], w[10], w[11], w[12], w[16], w[17], g[14],
                     self.dissipation, share)
        self._launch("totals", 1, w[10], w[11], w[16], w[6], w[8], self.dissipation,
                     self.dev["loop"][0], share)

    def _correct(self, stage, dt):
        sim = self.sim
        g, p, w, per = (self.dev[k] for k in ("grains", "pairs", "walls", "periodic"))
        integrator = int(sim.counters[loop.INTEGRATOR])
        self._launch("correct", sim.state.n, integrator, stage, dt,
                     sim.counters[loop.HISTORY_STEPS] > 0, int(sim.counters[loop.DIM]),
                     self.gravity, p[9], p[6], p[7], p[8], p[10], w[10], w[16], w[17], g[4], g[5],
                     g[9], g[10], g[0], g[13], g[1], g[2], g[3], g[6], g[7], g[12], per[0],
                     per[2], self.dev["loop"][1], self.squares)
        self._launch("bound", 1, self.squares, dt, self.dev["loop"][0])

    def run(self, steps):
        """Advance ``steps`` steps on the device (the step of core/loop.run_chunk)."""
        sim = self.sim
        self._upload()
        g, w = self.dev["grains"], self.dev["walls"]
        clock = self.dev["loop"][0]
        counters = sim.counters
        dt = float(sim.clock[loop.DT])
        integrator = int(counters[loop.INTEGRATOR])
        for _ in range(steps):
            if counters[loop.FORCE_REBUILD] == 0:
                self.k["decide"][1, 1](clock, w[5], w[9], w[6], self.control)
            rebuild_now = counters[loop.FORCE_REBUILD] != 0 or self.control.copy_to_host()[0]
            if rebuild_now:
                self._rebuild()
                counters[loop.FORCE_REBUILD] = 0
                g, w = self.dev["grains"], self.dev["walls"]
                clock = self.dev["loop"][0]
            if counters[loop.PRIMED] == 0:
                self._evaluate(0.0)
                self._correct(0, 0.0)
                counters[loop.PRIMED] = 1
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
        self._download()
        sim.state.time = sim.time
        sim.state.step = sim.step
