"""graindyn: granular dynamics simulator and virtual soil laboratory.

Importing compiles nothing: kernels compile on first use and are cached on disk.
"""
__version__ = "0.1.0"

from .core.species import ContactModel, Material
from .core.state import State, cell_order, sample_radii
from .core.triggers import EnergyRatioBelow, MaxSpeedBelow, Periodic
from .core.symmetry import Symmetry
from .core.walls import (Cylinder, Disk, Motion, Periodic as PeriodicBoundary, Plane, Segment,
                         box)
from .engines.soft.ensemble import Ensemble
from .engines.soft.simulation import Simulation, SimulationError


def open_run(path):
    """A run directory read back: its config, meta data, results, time series and the
    engine at its last checkpoint (runner.RunRecord; the runner is imported here, not
    with the package, as it brings the config layer)."""
    from .runner import RunRecord

    return RunRecord(path)


__all__ = ["open_run", "Simulation", "SimulationError", "Ensemble", "ContactModel", "Material", "State",
           "cell_order", "sample_radii", "EnergyRatioBelow", "MaxSpeedBelow", "Periodic", "Cylinder",
           "Disk", "Motion", "PeriodicBoundary", "Plane", "Segment", "Symmetry", "box",
           "__version__"]
