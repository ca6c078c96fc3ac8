"""The freely cooling gas protocol on the event-driven engine: Haff's law, from a config
through the runner to its files."""
import math

import pytest

from graindyn.analysis import gas
from graindyn.config import load
from graindyn.runner import execute

EXAMPLE = "examples/cooling_gas.toml"


def test_a_cooling_gas_follows_haff_until_it_clusters(tmp_path):
    """500 smooth grains at packing fraction 0.05, e = 0.9, for 0.6 Haff times t0 (the
    homogeneous stage): the fitted t0 within 5 % of Haff's 2 d / ((1 - e^2) Gamma0) with
    Enskog's Gamma0 at T0, the temperature falls as (1 + t/t0)^-2, and the run
    directory holds the samples and the figure."""
    config = load(EXAMPLE)
    n, phi, e, d = 500, 0.05, 0.9, 1e-3
    side = (n * math.pi / 6 * d**3 / phi) ** (1 / 3)
    config.grains.count = n
    config.walls.container.hi = [side] * 3
    config.walls.periodic = [[a, 0.0, side] for a in range(3)]
    mass = config.materials[0].density * math.pi / 6 * d**3
    rate = gas.enskog_collision_rate(n / side**3, d, 1e-9, mass, phi, 3)
    haff = 6 / ((1 - e**2) * rate)
    config.protocol.duration = 0.6 * haff
    config.protocol.sample_every = 0.02 * haff
    config.output.vtk_every = None
    results = execute(config, tmp_path / "run", show_progress=False, echo=lambda *a: None)
    assert results["haff_time_fitted_s"] == pytest.approx(haff, rel=0.05)
    assert results["final_temperature_J"] / results["initial_temperature_J"] == \
        pytest.approx(1 / 1.6**2, rel=0.05)
    assert (tmp_path / "run" / "cooling.csv").exists()
    assert (tmp_path / "run" / "figures" / "cooling.png").exists()
