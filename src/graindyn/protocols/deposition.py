"""The deposition protocol of a config run: insert the grains in the container (random
or loose lattice), settle them under gravity until the equilibrium criterion holds,
report the sample (protocols.prepare) and draw it.

A protocol runs as named phases; its progress lives in a JSON-able dict (``state``)
that checkpoints carry, so a resumed run picks up inside the phase where it stopped.
"""
import math

import numpy as np

from ..config import build
from ..config.models import BoxContainer, Config
from ..core.state import State, cell_order
from ..core.triggers import EnergyRatioBelow, MaxSpeedBelow
from ..engines.soft.simulation import Simulation
from .prepare import BoxRegion, CylinderRegion, lattice_insertion, random_insertion, \
    settle_report


class Deposition:
    """Gravity deposition in the config's container."""

    phases = ("settle",)

    @staticmethod
    def log(message):
        """Where the protocol reports its progress (the driver sets the run log)."""

    def __init__(self, config: Config):
        self.config = config
        self.dim = config.run.dim
        box = config.walls.container
        if isinstance(box, BoxContainer):
            lo, hi = np.asarray(box.lo, float), np.asarray(box.hi, float)
            self.cross_section = float(np.prod(hi[:-1] - lo[:-1]))
            self.bottom_wall = "zlo" if self.dim == 3 else "ylo"
            self.floor, self.ceiling = lo[-1], None if box.open_top else hi[-1]
        else:
            self.cross_section = math.pi * box.radius**2
            self.bottom_wall = "bottom"
            self.floor, self.ceiling = 0.0, None
        p = config.protocol
        self.criterion = EnergyRatioBelow(p.threshold) if p.criterion == "energy_ratio" \
            else MaxSpeedBelow(p.threshold)

    def _region(self, height):
        box = self.config.walls.container
        top = self.floor + height
        if self.ceiling is not None and top > self.ceiling:
            raise ValueError(f"the grains need an insertion region {height:.4g} m high but "
                             f"the closed box is only {self.ceiling - self.floor:.4g} m high: "
                             "open its top, make it taller or lower the count")
        if isinstance(box, BoxContainer):
            return BoxRegion(tuple(box.lo[:-1]) + (self.floor,), tuple(box.hi[:-1]) + (top,))
        return CylinderRegion(box.center, box.radius, self.floor, top)

    def create(self, rng):
        """The initial Simulation: grains drawn and inserted with ``rng``."""
        c, p = self.config, self.config.protocol
        radii = build.grain_radii(c, rng)
        solid = float(np.sum(4 / 3 * np.pi * radii**3 if self.dim == 3 else np.pi * radii**2))
        velocities = None
        if p.insertion == "random":
            positions, radii = random_insertion(
                radii, self._region(solid / (p.packing_fraction * self.cross_section)), rng,
                self.dim)
            # inserted largest first, at random places: put them cell by cell (cells of
            # about the neighbour cutoff), so that touching grains sit at nearby indices
            order = cell_order(positions, 2.2 * radii.max())
            positions, radii = positions[order], radii[order]
        else:
            spacing = 2 * radii.max() * (1 + p.lattice_gap)
            per_layer = max(1.0, (self.cross_section / spacing ** (self.dim - 1)) * 0.7)
            height = (math.ceil(radii.size / per_layer) + 2) * spacing
            positions, velocities = lattice_insertion(radii, self._region(height), rng,
                                                      self.dim, p.lattice_gap,
                                                      p.lattice_speed)
        material = c.material_index(c.grains.material)
        density = c.materials[material].density
        state = State.create(positions, radii, density, dim=self.dim,
                             materials=np.full(radii.size, material), velocities=velocities)
        return self.build(state)

    def build(self, state):
        """The Simulation of this config around ``state`` (also used when resuming)."""
        return Simulation(state, **build.simulation_kwargs(self.config))

    def run_phase(self, phase, sim, state, **run):
        """Run ``phase``; ``state`` (dict) records how far it got.  Returns sim.run's
        status ("stopped" means interrupted: call again with the same state).

        The equilibrium criterion is armed only after the free-fall time
        sqrt(2 h / g) of the highest grain above the floor: grains released at rest
        have E_kin/E_pot ~ 0 before they start to fall."""
        end = state.setdefault("end_step", sim.step + math.ceil(
            self.config.protocol.max_time / sim.dt - 1e-9))
        if "armed_step" not in state:
            up = self.dim - 1
            drop = float(np.max(sim.state.positions[:, up] - sim.state.radii)) - self.floor
            g = float(np.linalg.norm(sim.gravity))
            fall = math.sqrt(2.0 * max(drop, 0.0) / g) if g > 0 else 0.0
            state["armed_step"] = min(end, sim.step + math.ceil(fall / sim.dt))
        status = sim.run(steps=max(0, state["armed_step"] - sim.step), **run)
        if status == "done":
            status = sim.run(steps=end - sim.step, until=self.criterion, **run)
        if status != "stopped":
            state["reached"] = status == "condition"
        return status

    def phase_duration(self, name):
        """Longest simulated time [s] of a phase (for the progress bar)."""
        return self.config.protocol.max_time

    def tables(self, rundir, results):
        """Tables beside results.json: none for a deposition."""
        return []

    def results(self, sim, states):
        """The settled sample's report."""
        return settle_report(sim, states["settle"]["reached"], self.criterion,
                             self.bottom_wall, self.cross_section)

    def figures(self, rundir, series, results):
        """Kinetic energy and bottom force against time (from the saved series)."""
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        t = series["time [s]"]
        fig, ax = plt.subplots(1, 2, figsize=(10, 4))
        ax[0].semilogy(t, series["kinetic [J]"] + series["rotational [J]"])
        ax[0].set(xlabel="t [s]", ylabel="kinetic energy [J]")
        ax[1].plot(t, series[f"force_{self.bottom_wall} [N]"] / results["total_weight_N"])
        ax[1].axhline(1.0, color="k", lw=0.5)
        ax[1].set(xlabel="t [s]", ylabel="bottom force / weight [-]")
        fig.suptitle(f"{self.config.run.name}: packing fraction "
                     f"{results.get('packing_fraction', float('nan')):.3f}")
        return [save_figure(fig, rundir, "deposition.png")]


def save_figure(fig, rundir, name):
    """Write ``fig`` as figures/``name`` of the run directory, close it; the path."""
    import matplotlib.pyplot as plt

    fig.tight_layout()
    path = rundir.figures / name
    path.parent.mkdir(exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path
