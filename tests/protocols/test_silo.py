"""The 2D silo (protocols/silo.py, Pérez Sec. 4): a small silo flows, jams, is tapped
and flows again with every disk accounted for; the jam detector and the avalanche
bookkeeping on scripted sequences; Eq. 39; bad input refused before anything runs."""
import copy
import json
import math
import pathlib
import tomllib
from types import SimpleNamespace

import numpy as np
import pytest

from graindyn.config import ConfigError, build, validate
from graindyn.analysis.avalanches import cumulative
from graindyn.protocols.silo import Discharge
from graindyn.output import checkpoint
from graindyn.runner import execute

ROOT = pathlib.Path(__file__).resolve().parents[2]
EXAMPLE = tomllib.loads((ROOT / "examples" / "silo.toml").read_text())


def small(count=200, width=0.05, hole=0.015, **protocol):
    """The example silo, shrunk: ``count`` disks in a silo ``width`` [m] wide."""
    data = copy.deepcopy(EXAMPLE)
    data["grains"]["count"] = count
    data["walls"]["container"]["hi"] = [width, 0.6]
    data["protocol"].update(hole=hole, **protocol)
    data["output"] = {"series_every": 0.02, "figures": False}
    return data


def test_the_example_is_the_papers_silo():
    """examples/silo.toml holds Pérez's values in SI (N, d_ave, Delta_d, D, sigma, kappa,
    epsilon^2, mu, g, A, nu, c), the static friction spring kappa_s = kappa/3 that his
    Sec. 3.2 prescribes for disks, and a time step of 0.01 t_coll."""
    c = validate(EXAMPLE)
    m = c.materials[0]
    assert c.grains.count == 2000 and c.run.dim == 2
    assert (c.grains.diameter.min, c.grains.diameter.max) == (0.0045, 0.0055)
    assert c.walls.container.hi[0] - c.walls.container.lo[0] == 0.15
    assert (m.density, m.kn, m.friction_sliding, m.friction_static) == (8.0, 4e3, 0.5, 0.5)
    assert m.restitution ** 2 == pytest.approx(0.9, rel=1e-6)
    assert m.kt == pytest.approx(m.kn / 3, rel=1e-6)
    assert c.run.gravity == (0.0, -9.81, 0.0)
    p = c.protocol
    assert (p.tap_amplitude, p.tap_frequency, p.jam_factor) == (0.006, 8.0, 8.0)
    mass = 8.0 * np.pi * 0.0025**2
    t_coll = np.pi * np.sqrt(0.5 * mass / 4e3)
    assert c.engine.dt == pytest.approx(0.01 * t_coll, rel=0.01)


def test_a_small_silo_flows_jams_is_tapped_and_flows_again(tmp_path):
    """150 disks, R = 3: the initial discharge jams, taps break the arches, the disks
    that left are re-injected above the packing without overlapping, and at the end
    every disk is in the silo (or in flight just below its floor) with as many
    re-injections as avalanche sizes add up to; the taps leave the silo where it was."""
    config = validate(small(count=150, width=0.04, avalanches=2, discharge_time=3.0,
                            jam_factor=4.0, threshold=0.01))
    results = execute(config, tmp_path / "run", show_progress=False, echo=lambda *a: None)
    rows = results["avalanches"]
    assert rows[0]["first"] and not any(r["first"] for r in rows[1:])
    assert len(rows) == 3, rows                       # the first and two more
    assert results["exited"] == sum(r["size"] for r in rows) > 0
    assert all(r["end_s"] > r["start_s"] for r in rows)
    assert rows[1]["start_s"] == rows[0]["end_s"]     # an avalanche runs from tap to jam
    assert results["R"] == pytest.approx(0.015 / results["d_ave_m"])
    csv = (tmp_path / "run" / "avalanches.csv").read_text().splitlines()
    assert len(csv) == 1 + len(rows)
    arrays, meta, _, t = checkpoint.latest(tmp_path / "run" / "checkpoints")
    x, y = arrays["grains/positions"][:, 0], arrays["grains/positions"][:, 1]
    r = arrays["grains/radii"]
    d = results["d_ave_m"]
    assert np.all((x > 0) & (x < 0.04)), "a disk left through a side wall"
    assert np.all(y > -config.protocol.exit_depth * d - 1e-12), "a disk was not re-injected"
    assert y.size == config.grains.count
    # no two disks deeper in each other than the engine's overlap limit
    gap = np.hypot(x[:, None] - x, y[:, None] - y) - (r[:, None] + r)
    np.fill_diagonal(gap, np.inf)
    assert gap.min() > -config.engine.overlap_limit * r.min()
    names = [w.name for w in build.setup(config, build.protocol(config)).walls]
    silo = [k for k, n in enumerate(names) if n in ("floor_left", "floor_right", "xlo", "xhi")]
    assert np.all(np.abs(arrays["walls/offset"][silo]) < 1e-9), arrays["walls/offset"][silo]


class _Engine(SimpleNamespace):
    """What Discharge's jam check and bookkeeping read of an engine: time, the grains'
    velocities, masses and holds, walls by name, set_motion, kick."""

    def __init__(self):
        walls = SimpleNamespace(index=lambda name: name)
        super().__init__(time=0.0, walls=walls, motions=[], kicks=[],
                         state=SimpleNamespace(velocities=np.zeros((3, 3)),
                                               masses=np.full(3, 2.0),
                                               fixed=np.zeros(3, np.int8)))

    def set_motion(self, wall, motion):
        self.motions.append((wall, motion.kind))

    def kick(self, indices, delta_v):
        self.kicks.append((list(indices), tuple(delta_v)))


def test_jam_detector_and_avalanche_bookkeeping_on_a_scripted_sequence():
    """Jammed only when the largest speed is below v0/c AND no disk left for c t0; an
    avalanche runs from one tap to the next jam, a jam with no exit since the tap is a
    null avalanche; a tap moves every silo wall and ends fixing them; the bookkeeping
    lives in a JSON-able dict, so a copy taken mid-avalanche (a checkpoint) goes on to
    the same record."""
    protocol = SimpleNamespace(p=validate(small()).protocol, vessel=None,
                               log=lambda message: None)
    phase = Discharge(protocol)
    engine = _Engine()
    engine.walls.offset = {name: np.zeros(3) for name in
                           ("xlo", "xhi", "floor_left", "floor_right", "gate")}
    engine.place_wall = lambda wall, where: engine.walls.offset.__setitem__(wall, np.asarray(where))
    t0, v0, c = 0.02, 0.2, 8.0
    state = {"avalanches": [], "current": {"start_s": 0.0, "size": 0, "first": True},
             "last_exit_s": 0.0, "exited": 0, "tap_end_s": None, "jammed": False}
    engine.state.velocities[1, 1] = 0.5 * v0 / c
    engine.time = c * t0 * 0.99
    assert not phase.is_jammed(engine, state, t0, v0)         # a disk left too recently
    engine.time = c * t0 * 1.01
    assert phase.is_jammed(engine, state, t0, v0)
    engine.state.velocities[1, 1] = 1.01 * v0 / c
    assert not phase.is_jammed(engine, state, t0, v0)         # still moving
    # the first avalanche: 5 disks left, the last at t = 0.3
    state["current"]["size"], state["last_exit_s"] = 5, 0.3
    engine.time = 0.5
    phase.close_avalanche(engine, state)
    phase.tap(engine, state)
    assert sorted(w for w, kind in engine.motions if kind == "sinusoid") == sorted(
        ["xlo", "xhi", "floor_left", "floor_right", "gate"])
    assert state["tap_end_s"] == pytest.approx(0.5 + 0.5 / 8.0)
    engine.time = state["tap_end_s"]
    phase.end_tap(engine, state)
    assert [kind for _, kind in engine.motions[-5:]] == ["fixed"] * 5
    checkpointed = json.loads(json.dumps(state))              # mid-avalanche
    for record in (state, checkpointed):
        engine.time = 1.0
        phase.close_avalanche(engine, record)                  # nothing left: null
        phase.tap(engine, record)
        record["current"]["size"], record["last_exit_s"] = 3, 1.2
        engine.time = 1.5
        phase.close_avalanche(engine, record)
    assert checkpointed == json.loads(json.dumps(state))
    sizes = [(r["first"], r["size"]) for r in state["avalanches"]]
    assert sizes == [(True, 5), (False, 0), (False, 3)]
    first, null, last = state["avalanches"]
    assert first["duration_s"] == pytest.approx(0.3) and null["duration_s"] == 0.0
    assert first["mass_flow_kg_per_s"] == pytest.approx(5 / 0.3 * 2.0)
    assert last["start_s"] == 1.0 and last["duration_s"] == pytest.approx(0.2)


def _tapping(fixed, **settings):
    """A Discharge phase of the small silo with protocol ``settings`` and a scripted
    engine whose grains are held as ``fixed`` says: (phase, engine)."""
    protocol = SimpleNamespace(p=validate(small(**settings)).protocol, vessel=None,
                               log=lambda message: None)
    engine = _Engine()
    engine.walls.offset = {name: np.zeros(3) for name in
                           ("xlo", "xhi", "floor_left", "floor_right", "gate")}
    engine.place_wall = lambda wall, where: None
    engine.state.fixed = np.array(fixed, np.int8)
    return Discharge(protocol), engine


def test_a_parallel_tap_starts_the_disks_with_the_walls():
    """tap_start "parallel": the free disks get the walls' starting velocity 2 pi nu A
    upwards (held ones none); "walls" leaves the disks as they are."""
    for start, kicked in (("parallel", True), ("walls", False)):
        phase, engine = _tapping([0, 1, 0], tap_start=start)
        phase.tap(engine, {"current": {"start_s": 0.0, "size": 0, "first": True}})
        p = phase.p
        expected = [([0, 2], (0.0, 2 * np.pi * p.tap_frequency * p.tap_amplitude, 0.0))]
        assert engine.kicks == (expected if kicked else [])


def test_a_parallel_tap_ends_the_disks_with_the_walls():
    """tap_end "parallel": when the walls stop, half a period after the tap, the free
    disks lose the walls' velocity there, -2 pi nu A (so they gain 2 pi nu A upwards);
    "walls" leaves them as they are."""
    for end, kicked in (("parallel", True), ("walls", False)):
        phase, engine = _tapping([1, 0, 0], tap_end=end)
        engine.time = 2.0
        state = {"current": {"start_s": 0.0, "size": 0, "first": True}, "last_exit_s": 0.0}
        phase.tap(engine, state)
        engine.kicks.clear()
        engine.time = state["tap_end_s"]
        phase.end_tap(engine, state)
        if not kicked:
            assert engine.kicks == []
            continue
        ((indices, (dx, dy, dz)),) = engine.kicks
        p = phase.p
        assert indices == [1, 2] and dx == dz == 0.0
        assert dy == pytest.approx(2 * np.pi * p.tap_frequency * p.tap_amplitude, rel=1e-12)


def test_the_lip_setting_gives_the_floor_open_ends():
    """lip "open": the two floor segments beside the hole have open ends (the gate and
    the side walls are unchanged); "round", the default, keeps Pérez's rigid plate."""
    from graindyn.core.walls import Segment
    from graindyn.protocols.silo import FLOOR, GATE
    for lip in ("round", "open"):
        config = validate(small(lip=lip))
        walls = build.protocol(config).walls([], lambda name: 0)
        ends = {w.name: w.ends for w in walls if isinstance(w, Segment)}
        assert ends == {FLOOR[0]: lip, FLOOR[1]: lip, GATE: "round"}
    assert validate(small()).protocol.lip == "round"
    with pytest.raises(ConfigError, match="protocol.lip"):
        validate(small(lip="square"))


def test_cumulative_is_eq_39():
    """w(s) = number of avalanches of size >= s over the number of non-null ones; sizes
    1 + floor(X), X exponential of scale 30, have P(size >= s) = exp(-(s - 1)/30)
    exactly (20 000 draws: w within 4 standard errors below s = 100)."""
    s, w = cumulative([0, 1, 2, 2, 5, 0])
    np.testing.assert_allclose(w, [1.0, 0.75, 0.25, 0.25, 0.25])
    assert list(s) == [1, 2, 3, 4, 5]
    rng = np.random.default_rng(4)
    sizes = 1 + np.floor(rng.exponential(30.0, 20000))
    s, w = cumulative(sizes)
    keep = s < 100
    truth = np.exp(-(s[keep] - 1) / 30.0)
    error = np.sqrt(truth * (1 - truth) / sizes.size)
    assert np.all(np.abs(w[keep] - truth) < 4 * error + 1e-12)


@pytest.mark.parametrize("change, message", [
    ({"hole": 0.06}, "not narrower than the silo"),
    ({"hole": 0.004}, "not wider than the smallest disk"),
    ({"count": 5000}, "too narrow for 5000 disks"),
    ({"tap_amplitude": 0.0}, "protocol.tap_amplitude"),
    ({"tap_frequency": 0.0}, "protocol.tap_frequency"),
])
def test_bad_input_is_refused_with_one_clear_message(change, message):
    """A hole wider than the silo, a hole smaller than the smallest disk, a silo too
    narrow for its disks, a tap that cannot lift: refused at validation."""
    count = change.pop("count", 200)
    with pytest.raises(ConfigError, match=message) as err:
        validate(small(count=count, **change))
    assert str(err.value).count("\n") == 1, str(err.value)    # one problem, one line


@pytest.mark.parametrize("model", ["exp_square", "power_law"])
def test_the_fits_of_the_mean_avalanche_recover_known_parameters(model):
    """<s>(R) drawn from each law with Pérez's parameters at R = 3.4..4.5, 5 % noise:
    the fit recovers the parameters within 3 of its standard errors and chi2/dof is
    about 1."""
    from graindyn.analysis import avalanches

    R = np.arange(3.4, 4.51, 0.1)
    truth = avalanches.PAPER[model]
    mean = (avalanches.exp_square(R, **truth) if model == "exp_square"
            else avalanches.power_law(R, **truth))
    err = 0.05 * mean
    noisy = mean + err * np.random.default_rng(7).standard_normal(R.size)
    fit = (avalanches.fit_exp_square if model == "exp_square"
           else avalanches.fit_power_law)(R, noisy, err)
    for name, value in truth.items():
        if name != "s0":                       # s0 spans decades with the others
            assert abs(fit[name] - value) < 3 * fit[f"{name}_err"], (name, fit)
    assert 0.2 < fit["chi2_per_dof"] < 3.0, fit


def test_the_shift_of_perez_law_along_R_is_recovered_and_a_different_growth_is_told():
    """<s> drawn from Pérez's power law at R - 0.25 (a hole acting a quarter diameter
    narrower), 5 % noise, at R = 3.4..4.0: the one-parameter fit finds -0.25 within 3
    standard errors with chi2/dof about 1; data growing twice as fast in log <s> do not
    fit (chi2/dof far above 1)."""
    from graindyn.analysis import avalanches

    R = np.array([3.4, 3.5, 3.6, 3.8, 4.0])
    mean = avalanches.paper_shifted(R, -0.25)
    err = 0.05 * mean
    noisy = mean + err * np.random.default_rng(11).standard_normal(R.size)
    fit = avalanches.fit_paper_shift(R, noisy, err)
    assert abs(fit["shift"] + 0.25) < 3 * fit["shift_err"] and fit["shift_err"] < 0.02, fit
    assert 0.2 < fit["chi2_per_dof"] < 3.0, fit
    steeper = mean[0] * (mean / mean[0]) ** 2
    assert avalanches.fit_paper_shift(R, steeper, 0.05 * steeper)["chi2_per_dof"] > 20


def test_the_sweep_summary_pools_seeds_per_hole_size(tmp_path):
    """Two seeds at each of 4 hole sizes, avalanche sizes drawn from exponentials of
    known mean: the summary pools the seeds per R (the first avalanche of each run left
    out), writes the table, the JSON and the figure, and fits both laws."""
    from graindyn.analysis import avalanches

    rng = np.random.default_rng(3)
    points = []
    for R, scale in ((3.4, 20.0), (3.6, 35.0), (3.8, 60.0), (4.0, 110.0)):
        for seed in (1, 2):
            rows = [{"first": True, "size": 500}] + [
                {"first": False, "size": int(s)} for s in rng.exponential(scale, 300)]
            points.append(SimpleNamespace(status="finished", name=f"hole={R}/seed-{seed}",
                                          results={"R": R, "avalanches": rows,
                                                   "mean_flow_rate_per_s": 80.0}))
    paths = avalanches.summarize_sweep(tmp_path, points)
    assert all(p.exists() for p in paths)
    data = json.loads((tmp_path / "silo_sweep.json").read_text())
    rows = data["rows"]
    assert [r["R"] for r in rows] == [3.4, 3.6, 3.8, 4.0]
    assert [r["runs"] for r in rows] == [2, 2, 2, 2] and rows[0]["count"] == 600
    for r, scale in zip(rows, (20.0, 35.0, 60.0, 110.0)):
        # floor of an exponential of mean m has mean 1/(exp(1/m) - 1)
        expected = 1.0 / (np.exp(1.0 / scale) - 1.0)
        assert abs(r["mean"] - expected) < 4 * r["mean_err"]
    assert "B" in data["fits"]["exp_square"] and "gamma" in data["fits"]["power_law"]
    for r in rows:
        # each seed's own mean, their seed-to-seed error, the largest, the null error
        seeds = [np.mean([a["size"] for a in p.results["avalanches"][1:]])
                 for p in points if p.name.startswith(f"hole={r['R']}/")]
        assert r["seed_means"] == pytest.approx(seeds)
        assert r["seed_err"] == pytest.approx(abs(seeds[0] - seeds[1]) / 2)
        assert r["largest"] == max(r["sizes"])
        p_null = r["null_fraction"]
        assert r["null_fraction_err"] == pytest.approx(math.sqrt(p_null * (1 - p_null) / 600))
    md = (tmp_path / "silo_sweep.md").read_text()
    assert "| hole=3.4 | 3.400 | 2 | 600 |" in md
    # Pérez's power law (s0 = 8.5e5, R_c = 6.7, gamma = 8.2) gives 48 at R = 3.4
    assert "| 48 | nan | nan |" in md.splitlines()[6]


def test_the_cost_of_an_avalanche_is_read_from_each_run():
    """Simulated discharge time per avalanche (the settling left out, the first
    avalanche counted) and CPU seconds per simulated second of the last session."""
    from graindyn.analysis import avalanches

    results = {"settle": {"time_s": 1.0}, "time_s": 21.0, "dt_s": 1e-5,
               "steps_this_session": 500_000, "cpu_time_this_session_s": 250.0,
               "avalanches": [{"first": True, "size": 30}] + [{"first": False, "size": 3}] * 3}
    per_avalanche, cpu = avalanches._run_cost(results)
    assert per_avalanche == pytest.approx(5.0) and cpu == pytest.approx(50.0)
    [row] = avalanches.hole_rows([SimpleNamespace(status="finished", name="h/seed-1",
                                                  results={"R": 3.4, **results})])
    assert row["cpu_s_per_avalanche"] == pytest.approx(250.0)


def test_the_sweep_summary_pools_the_seeds_of_a_hole_whatever_their_measured_R():
    """Each seed measures R with its own mean diameter: two runs of one hole at
    R = 3.5049 and 3.5051 are one row (their mean R), two holes are two rows."""
    from graindyn.analysis import avalanches

    def point(folder, seed, R):
        return SimpleNamespace(status="finished", name=f"{folder}/seed-{seed}", results={
            "R": R, "avalanches": [{"first": True, "size": 9}, {"first": False, "size": 4}],
            "mean_flow_rate_per_s": 80.0})
    rows = avalanches.hole_rows([point("reference", 1, 3.5049), point("reference", 2, 3.5051),
                                 point("hole=0.017", 1, 3.4)])
    assert [r["runs"] for r in rows] == [1, 2]
    assert [r["point"] for r in rows] == ["hole=0.017", "reference"]
    assert rows[1]["R"] == pytest.approx(3.505) and rows[1]["sizes"] == [4, 4]


def test_points_that_share_a_hole_size_are_rows_of_their_own_and_are_not_fitted(tmp_path):
    """A sweep of another parameter at one hole (examples/silo_lip.toml): one row per
    point, each named, and no curve across R."""
    from graindyn.analysis import avalanches

    points = [SimpleNamespace(status="finished", name=f"{folder}/seed-{seed}", results={
        "R": 3.4, "avalanches": [{"first": True, "size": 9}] + [
            {"first": False, "size": s} for s in (scale, 2 * scale, 0)],
        "mean_flow_rate_per_s": 80.0})
        for folder, scale in (("reference", 10), ("lip=open", 30)) for seed in (1, 2)]
    avalanches.summarize_sweep(tmp_path, points)
    data = json.loads((tmp_path / "silo_sweep.json").read_text())
    assert sorted(r["point"] for r in data["rows"]) == ["lip=open", "reference"]
    assert {r["point"]: r["mean"] for r in data["rows"]} == {"reference": 10, "lip=open": 30}
    for name in ("exp_square", "power_law", "paper_shift"):
        assert "share a hole size" in data["fits"][name]["error"]
    md = (tmp_path / "silo_sweep.md").read_text()
    assert "| lip=open | 3.400 | 2 | 6 |" in md and "| reference | 3.400 | 2 | 6 |" in md
