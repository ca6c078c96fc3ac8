"""Ensemble: many independent simulations advanced together.

On the GPU (every member built with backend="gpu") the members run in one set of
kernel launches (engines/soft/gpu/engine.DeviceEnsemble): what makes sweeps of small samples fast
there.  On the CPU they run one after another.  Either way member k gives the numbers
it gives when run alone, to the bit.

>>> ens = Ensemble([make(seed) for seed in range(100)])          # doctest: +SKIP
>>> outcomes = ens.run(time=0.5, until=EnergyRatioBelow(1e-6))   # doctest: +SKIP

Members may differ in grains, walls, materials, time step, gravity, periodicity and
stop condition; on the GPU they must share the contact model, the dimension and the
integrator.
"""
from ...core.triggers import NO_CONDITION
from . import loop
from .simulation import SimulationError


class Ensemble:
    """K Simulations run side by side; ``sims`` is the list (all backend "cpu" or all
    backend "gpu")."""

    def __init__(self, sims):
        self.sims = list(sims)
        if not self.sims:
            raise ValueError("an ensemble needs at least one simulation")
        backends = {s.backend for s in self.sims}
        if len(backends) > 1:
            raise ValueError(f"an ensemble runs on one backend, got {sorted(backends)}")
        self.backend = backends.pop()
        self._device = None
        if self.backend == "gpu":
            from .gpu.layout import Layout
            Layout.check(self.sims)

    def run(self, steps=None, time=None, until=None, max_chunk=20000, between=None):
        """Advance every member ``steps`` steps or ``time`` seconds (a value for all or
        one per member), or until ``until`` holds for it (one condition, or one per
        member, None for none), as Simulation.run does for each.

        between : callback(ensemble) after every chunk; returning True stops the run.
        Returns one outcome per member: "done", "condition", "stopped", or the
        SimulationError that stopped it (a member that blows up stops alone).
        """
        k = len(self.sims)
        steps, time, until = (v if isinstance(v, (list, tuple)) else [v] * k
                              for v in (steps, time, until))
        if not len(steps) == len(time) == len(until) == k:
            raise ValueError(f"steps, time and until need one value per member ({k})")
        if self.backend == "cpu":
            return [self._run_one(s, n, t, u, max_chunk, between)
                    for s, n, t, u in zip(self.sims, steps, time, until)]
        ends = [s.begin_run(n, t, u) for s, n, t, u in zip(self.sims, steps, time, until)]
        outcomes = ["done" if s.step >= e else None for s, e in zip(self.sims, ends)]
        if self._device is None:
            from .gpu.engine import DeviceEnsemble
            self._device = DeviceEnsemble(self.sims)
        try:
            while None in outcomes:
                sizes = [0 if o is not None else s.chunk_size(e, max_chunk)
                         for s, e, o in zip(self.sims, ends, outcomes)]
                status, _ = self._device.chunk(sizes)
                for j, sim in enumerate(self.sims):
                    if outcomes[j] is not None:
                        continue
                    if status[j] == loop.CONDITION:
                        outcomes[j] = "condition"
                    elif sim.failure(status[j]) is not None:
                        outcomes[j] = sim.failure(status[j])
                    elif sim.step >= ends[j]:
                        outcomes[j] = "done"
                if None in outcomes and between is not None and between(self):
                    outcomes = [o if o is not None else "stopped" for o in outcomes]
        finally:
            for sim in self.sims:
                sim.counters[loop.COND_KIND] = NO_CONDITION
        return outcomes

    def _run_one(self, sim, steps, time, until, max_chunk, between):
        """One member on the CPU; ``between`` gets the ensemble."""
        try:
            return sim.run(steps=steps, time=time, until=until, max_chunk=max_chunk,
                           between=None if between is None else lambda _: between(self))
        except SimulationError as err:
            return err
