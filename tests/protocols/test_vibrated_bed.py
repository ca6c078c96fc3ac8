"""The vibrated bed protocol on the event-driven engine: a driven granular gas whose
mean floor force balances its weight."""
import math

import pytest

from graindyn.config import load
from graindyn.runner import execute


def test_a_vibrated_bed_of_hard_grains_is_held_up_by_its_floor(tmp_path):
    """100 grains released onto a floor shaken at Gamma = 5 for 0.6 s: over the second
    half the mean force of the collisions on the floor is the weight (momentum balance
    of a steady state, 10 % over 0.3 s), the bed is a gas (temperature > 0) lifted above
    its resting height, and the samples and figure are written."""
    config = load("examples/vibrated_bed.toml")
    config.grains.count = 100
    config.protocol.duration = 0.6
    config.protocol.settle_first = False     # released from the cloud (a settled bed
    #   shaken: tests/engine/event_driven/test_collapse.py)
    config.output.vtk_every = None
    results = execute(config, tmp_path / "run", show_progress=False, echo=lambda *a: None)
    a, f = config.protocol.amplitude, config.protocol.frequency
    assert results["gamma"] == pytest.approx(a * (2 * math.pi * f) ** 2 / 9.81, rel=1e-9)
    assert results["mean_floor_force_N"] == pytest.approx(results["weight_N"], rel=0.1)
    assert results["mean_temperature_J"] > 0
    assert results["mean_centre_height_m"] > 1e-3
    assert (tmp_path / "run" / "vibration.csv").exists()
    assert (tmp_path / "run" / "figures" / "vibration.png").exists()
