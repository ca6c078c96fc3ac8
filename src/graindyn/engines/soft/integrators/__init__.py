"""Integrators as stages around force evaluations, chosen by name (ids.NAMES) and
dispatched by integer id inside the compiled loop.  One module per family:
verlet.py (velocity Verlet with and without predictor, Verlet, leap-frog, optimized
velocity Verlet), beeman.py, gear.py; rotation.py holds the quaternion updates and
passes.py the two compiled passes over grains."""
from .ids import NAMES, SCHEMES, SLOTS, STAGES, history_names, integrator_id
from .passes import after_force, before_force

__all__ = ["NAMES", "SCHEMES", "SLOTS", "STAGES", "history_names", "integrator_id",
           "after_force", "before_force"]
