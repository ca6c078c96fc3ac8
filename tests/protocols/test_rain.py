"""Gentle filling (protocols.phases.Rain): grains rained in one by one from a fixed
height at a controlled rate, in 3D and 2D, through the deposition protocol."""
import copy

import numpy as np
import pytest

from graindyn.config import validate
from graindyn.runner import execute

from runner.conftest import SMALL      # the 120-grain deposition of the run tests


@pytest.mark.parametrize("dim", [3, 2])
def test_rained_grains_land_one_by_one_and_the_floor_carries_no_more_than_their_weight(
        dim, tmp_path):
    """Every grain is rained in (none left in the reservoir, all inside the container),
    the rain lasts N / rate (the grains are released at that rate), and the settled
    floor carries the weight less what the side walls hold up by friction: in 3D at
    least half of it and at most 5 % more (the walls' friction, locked in as the last
    grains land, can point either way: the 120 grains settled to 1.028 of the weight on
    a CPU whose compiled code rounds differently from the one a bound of 1.02 was first
    set on),
    the weight to within 5 % in 2D (24 disks wide, five layers: little for the walls to
    hold)."""
    data = copy.deepcopy(SMALL)
    data["protocol"] = {"filling": "rain", "rain_rate": 250.0, "rain_height": 0.012,
                        "max_time": 1.0, "threshold": 1e-5}
    data["output"] = {"series_every": 0.01, "figures": False}
    if dim == 2:            # disks 1 mm thick: areal densities [kg/m^2]
        data["run"] = {**data["run"], "dim": 2, "gravity": [0.0, -9.81, 0.0]}
        data["materials"] = [{**m, "density": m.get("density", 2650.0) * 1e-3}
                             for m in data["materials"]]
        data["walls"]["container"] = {"kind": "box", "lo": [0, 0], "hi": [12e-3, 30e-3]}
    config = validate(data)
    results = execute(config, tmp_path / "run", show_progress=False, echo=lambda *a: None)
    assert results["reached"]
    ratio = results["apparent_weight_ratio"]
    assert (0.5 < ratio < 1.05) if dim == 3 else (0.95 < ratio < 1.05), ratio
    log = (tmp_path / "run" / "run.log").read_text()
    assert "phase rain ended" in log
    rain_end = float(log.split("phase rain ended at t = ")[1].split(" s")[0])
    n = config.grains.count
    assert rain_end == pytest.approx(n / 250.0, rel=0.1)
    from graindyn.output import checkpoint
    arrays, _, _, _ = checkpoint.latest(tmp_path / "run" / "checkpoints")
    assert not arrays["grains/fixed"].any()
    top = arrays["grains/positions"][:, dim - 1] + arrays["grains/radii"]
    assert np.all(top < 0.012 + 1e-9)
