"""Integrators as stages around force evaluations, chosen by name (ids.NAMES) and
dispatched by integer id inside the compiled loop.  One module per family:
verlet.py (velocity Verlet with and without predictor, Verlet, leap-frog, optimized
velocity Verlet), beeman.py, gear.py; passes.py the two compiled passes over grains;
the quaternion updates they turn grains with are core/rotation.py."""
from .ids import NAMES, SCHEMES, SLOTS, STAGES, history_names, integrator_id
from .passes import after_force, before_force

__all__ = ["NAMES", "SCHEMES", "SLOTS", "STAGES", "history_names", "integrator_id",
           "after_force", "before_force"]
