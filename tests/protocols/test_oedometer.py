"""The oedometric test (protocols/oedometer.py): the servo wall against Hertz's law, the
stress ladder, a small oedometer run checked for equilibrium and force balance, and an
interrupted oedometer resumed to the same numbers."""
import copy
import json

import numpy as np
import pytest
import tomli_w

import graindyn as gd
from graindyn.config import ConfigError, validate
from graindyn.core.walls import Motion, Plane
from graindyn.output import checkpoint
from graindyn.output.rundir import Series
from graindyn.protocols.oedometer import MIN_AT_REST, fit_ladder, ladder
from graindyn.runner import execute

from cli_runs import cli, stop_when_logged



SMALL = {
    "run": {"name": "small_oedometer", "seed": 3},
    "grains": {"count": 100, "material": "sand",
               "diameter": {"min": 0.85e-3, "max": 1.15e-3}},
    "materials": [{"name": "sand", "youngs_modulus": 1e8, "poisson_ratio": 0.25,
                   "gamma_n": 6e5, "friction_sliding": 0.4, "tangential_damping": 1.0}],
    "contact": {"normal": "hertz", "damping": "viscoelastic", "tangential": "mindlin"},
    "walls": {"material": "sand",
              "container": {"kind": "cylinder", "radius": 2.5e-3, "height": 12e-3}},
    "engine": {"integrator": "optimized_velocity_verlet"},
    "protocol": {"kind": "oedometer", "packing_fraction": 0.25, "threshold": 1e-5,
                 "max_time": 0.3, "p0": 2e3, "p_max": 8e3, "unload": True,
                 "servo_time": 2e-3, "max_speed": 0.05, "level_max_time": 0.1},
    "output": {"series_every": 1e-3, "figures": True},
}


def test_ladder_doubles_up_to_p_max_and_back():
    assert ladder(1.0, 8.0, 2.0) == [(1.0, "loading"), (2.0, "loading"), (4.0, "loading"),
                                     (8.0, "loading")]
    assert [p for p, _ in ladder(1.0, 5.0, 2.0)] == [1.0, 2.0, 4.0, 5.0]
    down = ladder(1.0, 4.0, 2.0, unload=True)
    assert down[3:] == [(2.0, "unloading"), (1.0, "unloading")]


def _bauer_rows(moving):
    """Nine loading levels on Bauer's law (e0 = 0.8, h_s = 500 MPa, eta = 0.6) and one
    unloading level; the levels in ``moving`` are not at rest and 1 % too loose."""
    rows = []
    for level, p in enumerate(12.5e3 * 2.0 ** np.arange(9)):
        e = 0.8 * np.exp(-(p / 5e8) ** 0.6) * (1.01 if level in moving else 1.0)
        rows.append({"level": level, "branch": "loading", "at_rest": level not in moving,
                     "sigma_top_Pa": p, "trace_Pa": 2.2 * p, "void_ratio": e})
    return rows + [dict(rows[-2], level=9, branch="unloading", void_ratio=0.7)]


def test_bauer_fit_leaves_out_levels_not_at_rest():
    """A level still creeping when its time ran out does not enter the fit: the law is
    recovered exactly from the others, and the fit says which levels it used."""
    fit = fit_ladder(_bauer_rows(moving={0}))["vertical"]
    assert fit["levels"] == list(range(1, 9)) and fit["not_at_rest"] == [0]
    assert fit["h_s_Pa"] == pytest.approx(5e8, rel=1e-6)
    assert fit["eta"] == pytest.approx(0.6, rel=1e-6)
    assert fit["e0"] == pytest.approx(0.8, rel=1e-9)


def test_bauer_fit_uses_every_level_when_too_few_are_at_rest():
    """With fewer than MIN_AT_REST levels at rest all loading levels are fitted, and the
    ones not at rest are listed."""
    moving = set(range(9 - MIN_AT_REST + 1))
    fit = fit_ladder(_bauer_rows(moving=moving))["trace"]
    assert fit["levels"] == list(range(9)) and fit["not_at_rest"] == sorted(moving)
    assert fit["rms"] > 1e-3


@pytest.mark.parametrize("change, message", [
    (lambda c: c["protocol"].update(p_max=1e3), "p_max"),
    (lambda c: c["protocol"].update(piston_material="brass"), "piston_material"),
    (lambda c: c["run"].update(dim=2, gravity=[0, -9.81, 0]), "dim = 3"),
    (lambda c: c["protocol"].update(loading="piston", piston_mass=0.0), "piston_mass"),
    (lambda c: c["protocol"].update(loading="piston", piston_mass=-1.0), "piston_mass"),
    (lambda c: c["protocol"].update(loading="weight"), "loading"),
    (lambda c: c["protocol"].update(level_min_time=0.2), "level_min_time"),
])
def test_bad_oedometer_configs_are_refused(change, message):
    data = copy.deepcopy(SMALL)
    change(data)
    with pytest.raises(ConfigError, match=message):
        validate(data)


def test_servo_wall_holds_a_sphere_at_the_hertz_overlap():
    """A sphere between a fixed floor and a servo wall with target F, no gravity: at rest
    both overlaps are the Hertz overlap of F, (3 F / (4 E* sqrt(R)))^(2/3), and the
    force never exceeds the target by more than 1 % (the wall has no inertia)."""
    radius, target = 0.5e-3, 0.05
    mat = gd.Material(youngs_modulus=1e8, poisson_ratio=0.3, restitution=0.5,
                      friction_sliding=0.0)
    state = gd.State.create(np.array([[0.0, 0.0, radius]]), [radius], 2650.0)
    piston = Plane((0, 0, 2 * radius + 1e-6), (0, 0, -1), name="piston",
                   motion=Motion("servo", direction=(0, 0, -1), force=target, gain=0.2,
                                 max_speed=0.01))
    sim = gd.Simulation(state, [mat], gd.ContactModel("hertz", "tsuji", "coulomb"),
                        walls=[Plane((0, 0, 0), (0, 0, 1), name="floor"), piston],
                        gravity=(0.0, 0.0, 0.0))
    peak = []
    sim.run(time=0.02, every=[(gd.Periodic(steps=1), lambda s: peak.append(
        s.walls.normal_force(1)))])
    e_star = mat.youngs_modulus / (2 * (1 - mat.poisson_ratio**2))  # wall of the same material
    hertz = (3 * target / (4 * e_star * np.sqrt(radius))) ** (2 / 3)
    gap = sim.walls.offset[1, 2] + sim.walls.geometry[1, 2]
    assert sim.walls.normal_force(1) == pytest.approx(target, rel=1e-3)
    assert sim.walls.normal_force(0) == pytest.approx(target, rel=1e-3)
    assert 2 * radius - gap == pytest.approx(2 * hertz, rel=1e-3)
    assert max(peak) <= 1.01 * target


def _sphere_under_a_piston(target, restitution, dt=None):
    """A sphere between a fixed floor and a piston of 20 sphere masses pushed down by
    ``target`` [N], no gravity, the piston just above the sphere."""
    radius = 0.5e-3
    mat = gd.Material(youngs_modulus=1e8, poisson_ratio=0.3, restitution=restitution,
                      friction_sliding=0.0)
    state = gd.State.create(np.array([[0.0, 0.0, radius]]), [radius], 2650.0)
    mass = 20 * state.masses[0]
    piston = Plane((0, 0, 2 * radius + 1e-6), (0, 0, -1), name="piston",
                   motion=Motion("piston", direction=(0, 0, -1), force=target, mass=mass))
    damping = "none" if restitution is None else "tsuji"
    sim = gd.Simulation(state, [mat], gd.ContactModel("hertz", damping, "coulomb"),
                        walls=[Plane((0, 0, 0), (0, 0, 1), name="floor"), piston],
                        gravity=(0.0, 0.0, 0.0), dt=dt)
    return sim, mat, radius, mass


def test_massive_piston_comes_to_rest_at_the_hertz_overlap():
    """Damped contacts: the piston's fall onto the sphere rings down to the static
    Hertz overlap of its force at both contacts, (3 F / (4 E* sqrt(R)))^(2/3)."""
    target = 0.05
    sim, mat, radius, _ = _sphere_under_a_piston(target, 0.5)
    sim.run(time=0.05)
    e_star = mat.youngs_modulus / (2 * (1 - mat.poisson_ratio**2))
    hertz = (3 * target / (4 * e_star * np.sqrt(radius))) ** (2 / 3)
    gap = sim.walls.offset[1, 2] + sim.walls.geometry[1, 2]
    assert sim.walls.normal_force(1) == pytest.approx(target, rel=1e-4)
    assert sim.walls.normal_force(0) == pytest.approx(target, rel=1e-4)
    assert 2 * radius - gap == pytest.approx(2 * hertz, rel=1e-4)


def _energy_error(dt):
    """Peak-to-peak of the total energy of the undamped sphere and piston (kinetic of
    both, elastic, and the potential F z of the constant applied force) over the first
    and the second 5 ms of their bouncing, and the largest elastic energy [J]."""
    target = 0.05
    sim, _, _, mass = _sphere_under_a_piston(target, None, dt)
    totals, elastic = [], []

    def record(s):
        e = s.energies()
        piston = 0.5 * mass * float(s.walls.velocity[1] @ s.walls.velocity[1])
        totals.append(e["kinetic"] + e["elastic"] + piston + target * s.walls.offset[1, 2])
        elastic.append(e["elastic"])

    sim.run(time=0.01, every=[(gd.Periodic(time=1e-5), record)])
    assert min(elastic) == 0.0 < max(elastic)        # it bounced: the contacts opened
    half = len(totals) // 2
    return np.ptp(totals[:half]), np.ptp(totals[half:]), max(elastic)


def test_massive_piston_conserves_energy_to_first_order_without_drift():
    """Undamped, the energy of sphere, contacts and piston stays constant up to an error
    of first order in dt (the piston's semi-implicit Euler, core.walls) that does not
    grow with time: halving dt halves it, and the second 5 ms are no worse than the
    first; at the default step it is below 2 % of the energy exchanged."""
    first, second, swing = _energy_error(2.8e-6)
    finer, _, _ = _energy_error(1.4e-6)
    assert first / finer == pytest.approx(2.0, rel=0.1)
    assert second < 1.1 * first and first < 0.02 * swing


@pytest.fixture(scope="module")
def oedometer(tmp_path_factory):
    out = tmp_path_factory.mktemp("oedometer") / "run"
    results = execute(validate(SMALL), out, show_progress=False, echo=lambda *a: None)
    return out, results


def test_small_oedometer_ladder(oedometer):
    """Loading 2, 4, 8 kPa then unloading to 4 and 2 kPa: at rest at every level, e
    falls while loading and rises (elastic rebound) while unloading, but stays below
    the loading branch at the same stress (the compaction by rearrangement is not
    recovered); at each level the piston carries its target and the bottom plus the
    side-wall friction carry the piston force plus the weight."""
    out, results = oedometer
    rows = results["ladder"]
    assert [(r["target_Pa"], r["branch"]) for r in rows] == [
        (2e3, "loading"), (4e3, "loading"), (8e3, "loading"), (4e3, "unloading"),
        (2e3, "unloading")]
    assert all(r["at_rest"] for r in rows), [(r["target_Pa"], r["sigma_top_Pa"]) for r in rows]
    e = [r["void_ratio"] for r in rows]
    assert e[0] > e[1] > e[2] < e[3] < e[4], e
    assert e[3] < e[1] and e[4] < e[0], e
    for r in rows:
        piston = r["sigma_top_Pa"] * np.pi * 2.5e-3**2
        bottom = r["sigma_bottom_Pa"] * np.pi * 2.5e-3**2
        assert r["sigma_top_Pa"] == pytest.approx(r["target_Pa"], rel=0.01)
        # bottom + side-wall friction carry the piston force and the weight
        assert bottom + r["side_friction_N"] == pytest.approx(piston + r["weight_N"],
                                                               rel=0.01)
        assert 0.1 < r["K0"] < 2.0
        assert r["trace_Pa"] == pytest.approx(r["sigma_top_Pa"] + 2 * r["sigma_lateral_Pa"])
    assert set(results["bauer"]) == {"vertical", "trace"}
    assert (out / "ladder.csv").read_text().count("\n") == 6
    # the series follows the void ratio between levels: its last row before each
    # level's end (1 ms apart at most), the sample at rest, reads what the level recorded
    series = Series(out / "series.csv").read()
    last = np.searchsorted(series["time [s]"], [r["time_s"] for r in rows], "right") - 1
    assert series["void_ratio [-]"][last] == pytest.approx(e, rel=1e-4)
    assert series["piston_height [m]"][last] == pytest.approx([r["height_m"] for r in rows],
                                                              rel=1e-4)
    assert (out / "figures" / "oedometer.png").stat().st_size > 10_000
    assert "level 4 (unloading)" in (out / "run.log").read_text()


def test_the_figure_leaves_out_a_level_the_piston_never_reached(oedometer):
    """A level that ended before the piston reached the grains (sigma_top = 0, as after a
    settling cut short by max_time) is drawn without breaking the Bauer curve's
    logarithmic range: the figure is made from the other levels."""
    from graindyn.config.build import protocol
    from graindyn.config.load import load
    from graindyn.output.rundir import RunDirectory
    from graindyn.runner import draw

    out, results = oedometer
    unreached = copy.deepcopy(results)
    unreached["ladder"][0].update(sigma_top_Pa=0.0, trace_Pa=0.0)
    (path,) = [p for p in draw(RunDirectory(out), protocol(load(out / "config.toml")),
                               unreached) if p.name == "oedometer.png"]
    assert path.stat().st_size > 10_000


def test_small_oedometer_under_the_massive_piston_reaches_every_level(tmp_path):
    """loading = piston: the plate of the sample's mass, pushed by p A, comes to rest at
    every level of the ladder carrying p A, and e falls while loading."""
    data = copy.deepcopy(SMALL)
    data["protocol"].update(loading="piston", unload=False)
    data["output"]["figures"] = False
    results = execute(validate(data), tmp_path / "run", show_progress=False,
                      echo=lambda *a: None)
    rows = results["ladder"]
    assert [r["target_Pa"] for r in rows] == [2e3, 4e3, 8e3]
    assert all(r["at_rest"] for r in rows), [(r["target_Pa"], r["sigma_top_Pa"]) for r in rows]
    for r in rows:
        assert r["sigma_top_Pa"] == pytest.approx(r["target_Pa"], rel=0.01)
    e = [r["void_ratio"] for r in rows]
    assert e[0] > e[1] > e[2], e


def test_cloud_taller_than_the_cylinder_is_refused(tmp_path):
    """The piston starts at the top of the cylinder, so a random cloud that would reach
    above it (packing fraction 0.1: about 26 mm in the 12 mm cylinder) is refused with
    what to change, before any grain moves."""
    data = copy.deepcopy(SMALL)
    data["protocol"]["packing_fraction"] = 0.1
    with pytest.raises(ValueError, match=r"insertion region 0\.02\d+ m high but the "
                       r"closed cylinder is only 0\.012 m high: make it taller"):
        execute(validate(data), tmp_path / "run", show_progress=False, echo=lambda *a: None)
    data["walls"]["container"]["height"] = 30e-3
    data["protocol"].update(p_max=2e3, unload=False)
    data["output"]["figures"] = False
    results = execute(validate(data), tmp_path / "tall", show_progress=False,
                      echo=lambda *a: None)
    assert results["ladder"][0]["at_rest"]


def test_level_min_time_holds_every_level_under_its_load(tmp_path):
    """level_min_time: a level at rest earlier stays under its load until then, so each
    level lasts at least that long and still ends at rest."""
    data = copy.deepcopy(SMALL)
    data["protocol"].update(unload=False, level_min_time=0.02)
    data["output"]["figures"] = False
    results = execute(validate(data), tmp_path / "run", show_progress=False,
                      echo=lambda *a: None)
    rows = results["ladder"]
    assert all(r["at_rest"] for r in rows)
    ends = [r["time_s"] for r in rows]
    assert min(np.diff(ends)) >= 0.02


def test_oquendo_literal_reading_settles_denser_and_runs_the_ladder(tmp_path):
    """Oquendo's law read literally (no tangential spring: docs/contact_laws.md) against
    the spring reading, same grains and seed: static friction that only cancels the
    last step's slip lets the poured grains pack more densely (measured e0 0.91
    against 1.08), and the loaded sample still reaches every level of the ladder with
    e falling.  (Its first level, where the piston lands, does not come to rest within
    level_max_time: 1946 Pa or 1899 Pa for 2000 Pa, depending on the processor's vector
    instructions; only the later levels are required at rest, and at their load.)"""
    e0 = {}
    for law in ("oquendo", "oquendo_literal"):
        data = copy.deepcopy(SMALL)
        data["contact"] = {"normal": "hertz", "damping": "viscoelastic", "tangential": law}
        data["materials"][0].update(friction_static=0.4, friction_rolling=0.05)
        if law == "oquendo_literal":                   # it has no tangential dashpot
            del data["materials"][0]["tangential_damping"]
        data["protocol"].update(unload=False)
        data["output"]["figures"] = False
        rows = execute(validate(data), tmp_path / law, show_progress=False,
                       echo=lambda *a: None)["ladder"]
        assert [r["target_Pa"] for r in rows] == [2e3, 4e3, 8e3]
        assert all(r["at_rest"] for r in rows[1:]), [(r["target_Pa"], r["sigma_top_Pa"])
                                                     for r in rows]
        for r in rows[1:]:
            assert r["sigma_top_Pa"] == pytest.approx(r["target_Pa"], rel=0.05)
        e = [r["void_ratio"] for r in rows]
        assert e[0] > e[1] > e[2], e
        e0[law] = e[0]
    assert e0["oquendo_literal"] < e0["oquendo"] - 0.05, e0


def test_ladder_stops_early_when_the_load_outgrows_the_contact_law(tmp_path):
    """Loads far beyond what the soft grains can carry (2 MPa on E = 1e8 Pa: mean Hertz
    overlaps near 0.75 R) end the ladder at the first level that exceeds the overlap
    limit, with the reason, and keep the levels done (2 kPa: overlaps about 0.01 R),
    instead of losing the run."""
    data = copy.deepcopy(SMALL)
    data["protocol"].update(p0=2e3, factor=10.0, p_max=2e6)
    out = tmp_path / "run"
    results = execute(validate(data), out, show_progress=False, echo=lambda *a: None)
    stop = results["stopped_early"]
    done = [r["target_Pa"] for r in results["ladder"]]
    assert 1 <= stop["level"] == len(done)
    assert done == [2e3, 2e4, 2e5][:len(done)]
    assert stop["target_Pa"] == pytest.approx(2e3 * 10 ** stop["level"])
    assert "overlap exceeded 0.2" in stop["reason"]
    assert f"ladder stopped at level {stop['level']}" in (out / "run.log").read_text()


def test_interrupted_oedometer_resumes_to_the_same_numbers(oedometer, tmp_path):
    finished, results = oedometer
    (tmp_path / "run.toml").write_text(tomli_w.dumps(SMALL))
    run = tmp_path / "run"
    stop_when_logged(cli("run", tmp_path / "run.toml", "--out", run), run / "run.log",
                     "level 0")
    _, meta, _, t = checkpoint.read(run / "checkpoints" / "checkpoint.h5")
    assert meta["protocol"]["states"]["load"]["level"] >= 1
    assert t < results["ladder"][-1]["time_s"]
    proc = cli("run", "--resume", run)
    out, _ = proc.communicate(timeout=900)
    assert proc.returncode == 0, out
    resumed = json.loads((run / "results.json").read_text())
    assert resumed["ladder"] == json.loads((finished / "results.json").read_text())["ladder"]


def test_oedometer_of_rigid_grains_holds_every_level_and_recovers_nothing(tmp_path):
    """SMALL, 50 grains, on the contact dynamics engine (rigid grains, e_n = 0.3): at rest at every
    level, the piston carrying its target and the bottom plus side friction the piston
    plus the weight; no contact compresses, so the sample does not rebound when
    unloaded: the void ratio after unloading is no larger than at the peak (to 1e-6)."""
    data = copy.deepcopy(SMALL)
    data["materials"] = [{"name": "sand", "restitution": 0.3, "friction_sliding": 0.4,
                          "friction_static": 0.4}]
    data["grains"]["count"] = 50
    data["engine"] = {"kind": "contact_dynamics", "dt": 5e-5}
    results = execute(validate(data), tmp_path / "run", show_progress=False,
                      echo=lambda *a: None)
    rows = results["ladder"]
    assert all(r["at_rest"] for r in rows), [(r["target_Pa"], r["sigma_top_Pa"]) for r in rows]
    area = np.pi * 2.5e-3**2
    for r in rows:
        assert r["sigma_top_Pa"] == pytest.approx(r["target_Pa"], rel=0.01)
        assert r["sigma_bottom_Pa"] * area + r["side_friction_N"] == pytest.approx(
            r["sigma_top_Pa"] * area + r["weight_N"], rel=0.01)
        assert r["elastic_J"] == 0.0
    e = [r["void_ratio"] for r in rows]
    assert e[3] <= e[2] * (1 + 1e-6) and e[4] <= e[2] * (1 + 1e-6), e
