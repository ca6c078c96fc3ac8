"""Protocols built from phases: a protocol made only of existing phases (settle, then
hold) joins the registry and runs from a config like the built-in ones; composite
triggers fire where their parts say."""
import copy
import json
from typing import Literal

import numpy as np
import pytest

import graindyn as gd
from graindyn.config import validate
from graindyn.core.triggers import After, Before, Periodic
from graindyn.protocols import PROTOCOLS, Protocol, register
from graindyn.protocols.phases import (Hold, Settle, SettleSettings,
                                       preparation_friction)
from graindyn.runner import execute
from graindyn.schema import Float

from runner.conftest import SMALL      # the 120-grain deposition of the run tests


class SettleHoldSettings(SettleSettings):
    kind: Literal["settle_hold"] = "settle_hold"
    hold: Float = 0.01


class SettleHold(Protocol):
    """Settle, then hold the settled sample for ``hold`` seconds."""

    kind = "settle_hold"
    settings = SettleHoldSettings

    def __init__(self, settings, vessel):
        super().__init__(settings, vessel)
        self.phases = (Settle(settings, vessel), Hold(settings.hold))


@pytest.fixture
def settle_hold():
    register(SettleHold)
    yield SettleHold
    del PROTOCOLS["settle_hold"]


def test_a_protocol_of_existing_phases_runs_from_a_config(settle_hold, tmp_path):
    """Settle, then hold: the config names the new kind, validation checks its fields,
    the run goes through both phases, the hold lasts its time to within a step, and a
    settled bed held at rest stays at rest: its kinetic energy stays below the settle
    criterion's share of the potential energy and the floor carries the weight."""
    data = {**SMALL, "protocol": {"kind": "settle_hold", "max_time": 0.3, "hold": 0.01,
                                  "criterion": "energy_ratio", "threshold": 1e-4},
            "output": {"series_every": 2e-3, "figures": False}}
    with pytest.raises(Exception, match="protocol.hold"):
        validate({**data, "protocol": {**data["protocol"], "hold": "long"}})
    config = validate(data)
    assert type(config.protocol) is SettleHoldSettings
    results = execute(config, tmp_path / "run", show_progress=False, echo=lambda *a: None)
    settle = results["settle"]
    assert settle["reached"]
    log = (tmp_path / "run" / "run.log").read_text()
    assert "phase settle ended" in log and "phase hold ended" in log
    assert "phase settle:" not in log            # a verdict only when the criterion fails
    series = np.genfromtxt(tmp_path / "run" / "series.csv", delimiter=",", names=True)
    t_end = series["time_s"][-1]
    assert t_end == pytest.approx(settle["time_s"] + 0.01, abs=2 * results["dt_s"])
    held = series["time_s"] >= settle["time_s"]
    kinetic = series["kinetic_J"][held] + series["rotational_J"][held]
    assert np.all(kinetic < 1e-2 * abs(series["gravitational_J"][0] -
                                       series["gravitational_J"][-1]))
    weight = settle["total_weight_N"]
    assert series["force_zlo_N"][-1] == pytest.approx(weight, rel=0.1)
    meta = json.loads((tmp_path / "run" / "meta.json").read_text())
    assert meta["engine"] == "soft"


def test_a_settling_cut_short_says_so_in_the_run_log(settle_hold, tmp_path):
    """Settling stopped by max_time while the grains still fall: the run log says that
    the criterion was not met and at what E_kin/E_pot, the report names no grains (the
    whole bed still moves)."""
    data = {**SMALL, "protocol": {"kind": "settle_hold", "max_time": 0.01, "hold": 0.0},
            "output": {"series_every": 2e-3, "figures": False}}
    results = execute(validate(data), tmp_path / "run", show_progress=False,
                      echo=lambda *a: None)
    settle = results["settle"]
    assert not settle["reached"] and settle["kinetic_holders"] == []
    assert settle["energy_ratio"] > 1e-6
    log = (tmp_path / "run" / "run.log").read_text()
    assert (f"phase settle: EnergyRatioBelow(ratio=1e-06) not met in 0.01 s: E_kin/E_pot = "
            f"{settle['energy_ratio']:.3g}") in log


def test_grains_settled_without_friction_pack_denser(tmp_path):
    """protocol.settle_friction = 0: the grains settle frictionless (denser than with
    their own mu = 0.5, the classic way to prepare a dense sample) and get their
    friction back after the settling; an engine without friction coefficients to
    change refuses it."""
    base = {**SMALL, "protocol": {"kind": "deposition", "max_time": 0.3,
                                  "criterion": "energy_ratio", "threshold": 1e-4},
            "output": {"series_every": 5e-3, "figures": False}}
    packings = {}
    for friction in (None, 0.0):
        data = copy.deepcopy(base)
        if friction is not None:
            data["protocol"]["settle_friction"] = friction
        results = execute(validate(data), tmp_path / f"run_{friction}", show_progress=False,
                          echo=lambda *a: None)
        packings[friction] = results["packing_fraction"]
    assert packings[0.0] > packings[None] + 0.01, packings


def test_settle_friction_is_set_for_the_settling_and_taken_back():
    """preparation_friction gives the engine settle_friction, then None (the materials'
    own) at the end; nothing when it is not set; an engine without friction
    coefficients to change refuses it."""
    calls = []

    class Engine:
        def set_friction(self, value=None):
            calls.append(value)

    settings = SettleSettings(settle_friction=0.1)
    preparation_friction(Engine(), settings, True)
    preparation_friction(Engine(), settings, False)
    preparation_friction(Engine(), SettleSettings(), True)
    assert calls == [0.1, None]
    with pytest.raises(ValueError, match="settle_friction needs an engine"):
        preparation_friction(object(), settings, True)


def test_composite_triggers_fire_where_their_parts_say():
    """Periodic(steps=10) & After(t) fires every 10 steps from t on; Periodic(steps=10)
    | Periodic(steps=15) at the union of both; Before(t) alone is refused (no instants
    of its own)."""
    state = gd.State.create(np.array([[0.0, 0.0, 0.0]]), [1e-3], 2650.0)
    sim = gd.Simulation(state, [gd.Material()], gravity=(0, 0, 0), dt=1e-6)
    late, union, early = [], [], []
    sim.run(steps=60, every=[
        (Periodic(steps=10) & After(30.5e-6), lambda s: late.append(s.step)),
        (Periodic(steps=10) | Periodic(steps=15), lambda s: union.append(s.step)),
        (Periodic(steps=20) & Before(30e-6), lambda s: early.append(s.step))])
    assert late == [40, 50, 60]
    assert union == [10, 15, 20, 30, 40, 45, 50, 60]
    assert early == [20]
    with pytest.raises(TypeError, match="no Periodic"):
        sim.run(steps=1, every=[(Before(1.0), lambda s: None)])
