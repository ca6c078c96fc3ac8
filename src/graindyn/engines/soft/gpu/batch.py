"""Many whole runs on one GPU, each written as ordinary Python (ensembles).

A protocol (settle, then load level by level, with checks between chunks) drives its
Simulation with Python between compiled chunks.  ``Batch.run(jobs)`` runs each job (a
callable: a sweep point, a protocol) in its own thread; whenever a job's Simulation
with backend "gpu" asks for a chunk, the thread waits, and once every running job is
waiting (or done) their chunks run together as one ensemble (engine.DeviceEnsemble:
one set of kernel launches for all of them).  The jobs' code is unchanged: triggers,
stop conditions, checkpoints and errors behave as in a run alone, and every job gets
the numbers it gets alone, to the bit.  The chunks run in the calling thread; between
chunks a job's own calls (energies, contacts, snapshots) may launch kernels too, so
the job threads take turns: one at a time runs, holding the batch's baton, and lets go
of it while it waits for a round.  So no two threads ever launch kernels at once: the
CUDA simulator's kernels are not thread-safe (a launch configures the kernel object
itself, and swaps its module's ``cuda`` for the launch's), and the members' scratch
arrays are shared.

Members of one round that cannot share kernels (another contact model, dimension or
integrator) run as separate ensembles in that round.
"""
import threading

import numpy as np

from .. import loop

_LOCAL = threading.local()


def current():
    """The Batch the calling thread's chunks go to, or None."""
    return getattr(_LOCAL, "batch", None)


class Batch:
    """Runs jobs in threads and their Simulations' chunks as ensembles."""

    def __init__(self):
        self._lock = threading.Condition()
        self._baton = threading.Lock()       # held by the one job thread that runs
        self._requests = {}          # Simulation -> (job index, steps asked)
        self._results = {}
        self._running = 0
        self._engines = {}           # key of a group of simulations -> DeviceEnsemble
        self.rounds = 0

    def chunk(self, sim, nsteps):
        """Called from a job thread by Simulation._chunk: wait for the next round and
        return its (status, steps done) for ``sim``; raises in this job what made the
        round fail."""
        self._baton.release()
        try:
            with self._lock:
                self._requests[sim] = (_LOCAL.index, int(nsteps))
                self._lock.notify_all()
                while sim not in self._results:
                    self._lock.wait()
                result = self._results.pop(sim)
        finally:
            self._baton.acquire()
        if isinstance(result, BaseException):
            raise result
        return result

    def run(self, jobs, done=None):
        """Run every callable of ``jobs`` in its own thread, their chunks in shared
        rounds, until all have returned.  ``done(index, result)`` is called (in this
        thread) as each job ends; a job that raises has its exception as result.
        Returns the results in job order."""
        results = [None] * len(jobs)
        finished = []

        def member(index, job):
            _LOCAL.batch = self
            _LOCAL.index = index
            with self._baton:
                try:
                    result = job()
                except BaseException as err:      # reported to the caller, never lost
                    result = err
            with self._lock:
                results[index] = result
                finished.append(index)
                self._running -= 1
                self._lock.notify_all()

        threads = [threading.Thread(target=member, args=(k, job), daemon=True,
                                    name=f"graindyn-batch-{k}") for k, job in enumerate(jobs)]
        self._running = len(threads)
        for t in threads:
            t.start()
        reported = 0
        while True:
            with self._lock:
                while len(self._requests) < self._running:
                    self._lock.wait()
                requests = dict(self._requests)
                self._requests.clear()
                ended = finished[reported:]
                reported = len(finished)
            for index in ended:
                if done is not None:
                    done(index, results[index])
            if not requests:
                if self._running == 0:
                    break
                continue
            try:
                outcome = self._round(requests)
            except Exception as err:        # the device failed: each waiting job gets it
                outcome = dict.fromkeys(requests, err)
            with self._lock:
                self._results.update(outcome)
                self._lock.notify_all()
        for t in threads:
            t.join()
        return results

    def _round(self, requests):
        """One chunk for every waiting simulation: {sim: (status, done)}."""
        from .engine import DeviceEnsemble

        self.rounds += 1
        groups = {}
        for sim in sorted(requests, key=lambda s: requests[s][0]):       # job order
            key = (sim.model_ids.tobytes(), sim.history_size, int(sim.counters[loop.DIM]),
                   int(sim.counters[loop.INTEGRATOR]))
            groups.setdefault(key, []).append(sim)
        out = {}
        engines = {}
        for sims in groups.values():
            key = tuple(id(s) for s in sims)
            engine = self._engines.get(key) or DeviceEnsemble(sims)
            engines[key] = engine
            status, steps = engine.chunk(np.array([requests[s][1] for s in sims]))
            for s, code, n in zip(sims, status, steps):
                out[s] = (int(code), int(n))
        self._engines = engines      # keep only the groups of this round
        return out
