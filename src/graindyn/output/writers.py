"""Writers: what a run writes while it goes, each when its trigger (core.triggers) fires,
seeing only the engine interface (core.engine.Engine).  A writer's resume state
(``resume_state``) goes into every checkpoint, and a resumed run hands it back
(``resume``) with the checkpoint's simulated time, so the writer drops what it wrote
after the checkpoint and goes on as the uninterrupted run would have.
"""
import numpy as np

from ..analysis.energy import energy_budget
from ..analysis.gas import granular_temperature
from ..analysis.packing import coordination_number
from .network import draw_network
from .rundir import Series
from .vtk import VtkSeries


def series_row(engine):
    """One row of the standard time series (column names carry the units): energies,
    largest speed, coordination, granular temperatures (analysis.gas) and the force on
    each wall; the same columns for every engine and backend (collision counts, which
    not every engine keeps, are recorded by the protocols that need them)."""
    e = energy_budget(engine)
    v = engine.state.velocities
    speed = np.sqrt(np.max(np.einsum("ij,ij->i", v, v), initial=0.0))
    row = {"time [s]": engine.time, "kinetic [J]": e["kinetic"],
           "rotational [J]": e["rotational"], "gravitational [J]": e["gravitational"],
           "elastic [J]": e["elastic"], "dissipated_normal [J]": e["dissipated_normal"],
           "dissipated_tangential [J]": e["dissipated_tangential"],
           "wall_work [J]": e["wall_work"], "max_speed [m/s]": speed,
           "coordination [-]": coordination_number(engine)}
    row["temperature [J]"], row["rotational_temperature [J]"] = \
        granular_temperature(engine.state)
    for k, wall in enumerate(engine.walls.walls):
        row[f"force_{wall.name} [N]"] = engine.walls.normal_force(k)
    return row


class Writer:
    """Writes ``write(engine)`` whenever ``trigger`` fires (None: only at the start and
    the end of a run); ``name`` keys its resume state in checkpoints."""

    name = "writer"

    def __init__(self, trigger):
        self.trigger = trigger

    def write(self, engine):
        raise NotImplementedError

    def resume_state(self):
        """What the writer needs to resume (JSON-able), saved in checkpoints."""
        return {}

    def resume(self, state, time):
        """Go on from a checkpoint at simulated ``time`` [s] whose resume state is
        ``state``: forget what was written after it."""


class SeriesWriter(Writer):
    """The run's time series (series.csv: ``row(engine)`` per firing; default
    series_row), flushed row by row."""

    name = "series"

    def __init__(self, path, trigger, row=series_row):
        super().__init__(trigger)
        self.series = Series(path)
        self.row = row
        self.last_time = None

    def write(self, engine):
        if self.last_time == engine.time:
            return
        self.series.append(self.row(engine))
        self.last_time = engine.time

    def resume_state(self):
        return {"last_time": self.last_time}

    def resume(self, state, time):
        self.series.truncate(time)
        self.last_time = state.get("last_time")


class VtkWriter(Writer):
    """VTK snapshots of grains, walls and optionally contacts (output.vtk.VtkSeries)."""

    name = "vtk"

    def __init__(self, folder, trigger, contacts=False):
        super().__init__(trigger)
        self.vtk = VtkSeries(folder, contacts)

    def write(self, engine):
        self.vtk.write(engine)

    def resume_state(self):
        return {"entries": self.vtk.entries}

    def resume(self, state, time):
        self.vtk.entries = [tuple(e) for e in state.get("entries", [])]
        self.vtk.truncate(time)


class NetworkWriter(Writer):
    """Pictures of the grains to scale and their force network (output.network):
    ``folder``/network_000003.png, the fourth picture."""

    name = "network"

    def __init__(self, folder, trigger, title=""):
        super().__init__(trigger)
        self.folder = folder
        self.title = title
        self.times = []

    def write(self, engine):
        if self.times and self.times[-1] == engine.time:
            return
        draw_network(engine, self.folder / f"network_{len(self.times):06d}.png",
                     title=f"{self.title}, t = {engine.time:.4g} s")
        self.times.append(engine.time)

    def resume_state(self):
        return {"times": self.times}

    def resume(self, state, time):
        self.times = [t for t in state.get("times", []) if t <= time]
        for path in self.folder.glob("network_*.png"):
            if int(path.stem.rsplit("_", 1)[1]) >= len(self.times):
                path.unlink()
