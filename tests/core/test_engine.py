"""Engine correctness: neighbour lists and force gather against O(N^2) twins, contact
history across rebuilds and storage growth, conservation laws, order of accuracy,
determinism, blow-up detection and the 2D plane constraint."""
import sys
from pathlib import Path

import numba
import numpy as np
import pytest

import graindyn as gd
from graindyn.engines.soft import loop
from graindyn.physics.contact import contact_energy
from graindyn.physics.registry import COL

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
import naive  # noqa: E402

R = 1e-3           # reference radius [m]
RHO = 2650.0       # density [kg/m^3] (areal [kg/m^2] in 2D)
KN = 1e3           # linear stiffness [N/m]


# ---------------------------------------------------------------------------- helpers
def lattice(n, spacing, dim, rng, jitter=0.1):
    """n points on a jittered square/cubic lattice of ``spacing`` [m], lowest corner at
    spacing/2; returns (positions (n, 3), box length per axis (cells * spacing))."""
    side = int(np.ceil(n ** (1.0 / dim) - 1e-9))
    grid = np.stack(np.meshgrid(*[np.arange(side)] * dim, indexing="ij"), -1).reshape(-1, dim)
    grid = grid[rng.permutation(len(grid))[:n]]
    pos = np.zeros((n, 3))
    pos[:, :dim] = (grid + 0.5 + rng.uniform(-jitter, jitter, (n, dim))) * spacing
    return pos, side * spacing


def random_velocities(n, dim, speed, rng):
    v = np.zeros((n, 3))
    v[:, :dim] = rng.normal(0.0, speed, (n, dim))
    return v


def listed_pairs(sim):
    """(i, j) arrays of the half neighbour list, in list order."""
    start, partners = sim.pairs.start, sim.pairs.partners
    n = sim.state.n
    m = int(start[n])
    owner = np.repeat(np.arange(n), np.diff(start))
    return owner, partners[:m].astype(np.int64)


def pair_index(sim, i, j):
    """Index k of pair (i, j), i < j, in the list (or -1)."""
    start, partners = sim.pairs.start, sim.pairs.partners
    ks = np.nonzero(partners[start[i]:start[i + 1]] == j)[0]
    return int(start[i] + ks[0]) if ks.size else -1


def lengths_of(sim):
    return sim.walls.periodic_length * (sim.walls.periodic_flag != 0)


def hooke_material(friction=0.0, kt=0.0, restitution=None):
    return gd.Material(density=RHO, kn=KN, kt=kt, friction_sliding=friction,
                       friction_static=friction, restitution=restitution)


# ------------------------------------------------------------------ 2. neighbour list
def _gas(case, seed=1):
    """A dense random gas (hooke, elastic, frictionless) for the neighbour-list checks."""
    rng = np.random.default_rng(seed)
    dim = 2 if case.startswith("2d") else 3
    n = 300 if dim == 3 else 250
    if case == "3d_bimodal_5to1_periodic":
        radii = np.where(rng.uniform(size=n) < 0.3, R, R / 5.0)
    else:
        radii = rng.uniform(0.5 * R, 1.5 * R, n)
    pos, length = lattice(n, 2.1 * radii.max(), dim, rng, jitter=0.02)
    # areal density in 2D chosen so that a disk weighs what a sphere of radius R does
    rho = RHO if dim == 3 else 4.0 / 3.0 * RHO * R
    v = random_velocities(n, dim, 0.3, rng) * np.sqrt(R / radii)[:, None]  # small: faster
    st = gd.State.create(pos[:, :dim] if dim == 2 else pos, radii, rho, dim=dim,
                         velocities=v)
    kwargs = dict(gravity=(0.0, 0.0, 0.0))
    if case in ("3d_poly_periodic", "3d_bimodal_5to1_periodic"):
        kwargs["periodic"] = [gd.PeriodicBoundary(a, 0.0, length) for a in range(3)]
    elif case == "2d_poly_periodic_x":
        kwargs["periodic"] = [gd.PeriodicBoundary(0, -0.37 * length, 0.63 * length)]
        kwargs["walls"] = [gd.Plane((0, 0, 0), (0, 1, 0)), gd.Plane((0, length, 0), (0, -1, 0))]
    elif case == "3d_poly_box":
        kwargs["walls"] = gd.box((0, 0, 0), (length,) * 3, open_top=False)
    elif case == "2d_poly_box":
        kwargs["walls"] = gd.box((0, 0), (length, length), open_top=False, dim=2)
    # "3d_free": no walls, the cloud spreads out (exercises the coarse-grid path)
    mat = gd.Material(density=rho, kn=KN)
    return gd.Simulation(st, [mat], gd.ContactModel("hooke"), skin=0.3 * R, **kwargs)


GAS_CASES = ["3d_poly_box", "3d_poly_periodic", "3d_bimodal_5to1_periodic", "2d_poly_box",
             "2d_poly_periodic_x", "3d_free"]


@pytest.mark.parametrize("case", GAS_CASES)
def test_neighbour_list_matches_naive_search(case):
    sim = _gas(case)
    st = sim.state
    lengths = lengths_of(sim)
    skin = float(sim.clock[loop.SKIN])
    checks = []

    def check(s):
        i, j = listed_pairs(s)
        assert np.all(j > i)
        listed = set(zip(i.tolist(), j.tolist()))
        assert len(listed) == i.size, "a pair is listed twice"
        # exactly the pairs within the cut-off at the last build
        assert listed == naive.pairs_within(s.reference_positions, st.radii, skin, lengths)
        # every pair touching now is listed, and contacts() reports exactly those
        touching = naive.touching_pairs(st.positions, st.radii, lengths)
        assert touching <= listed
        c = s.contacts()
        assert set(zip(c.i.tolist(), c.j.tolist())) == touching
        checks.append((s.rebuilds, len(touching)))

    sim.run(steps=3000, every=[(gd.Periodic(steps=50), check)])
    assert len(checks) == 60
    assert sim.rebuilds >= 20, sim.rebuilds            # many rebuilds happened
    assert sum(c for _, c in checks) > 100             # and the gas was colliding
    if st.dim == 2:
        assert np.all(st.positions[:, 2] == 0.0)


def _settling(seed=3):
    """200 grains with friction and damping raining into a box: the pair count grows."""
    rng = np.random.default_rng(seed)
    nx, nz, spacing = 5, 8, 2.6 * R
    grid = np.stack(np.meshgrid(np.arange(nx), np.arange(nx), np.arange(nz),
                                indexing="ij"), -1).reshape(-1, 3)
    pos = (grid + 0.5 + rng.uniform(-0.1, 0.1, grid.shape)) * spacing
    radii = rng.uniform(0.6 * R, 1.2 * R, len(pos))
    st = gd.State.create(pos, radii, RHO, velocities=random_velocities(len(pos), 3, 0.1, rng))
    model = gd.ContactModel("hooke", "linear", "cundall_strack")
    mat = hooke_material(friction=0.5, kt=2.0 / 7.0 * KN, restitution=0.5)
    return gd.Simulation(st, [mat], model, skin=0.2 * R,
                         walls=gd.box((0, 0, 0), (nx * spacing, nx * spacing, 3 * nz * spacing)))


@pytest.mark.parametrize("integrator", ["velocity_verlet", "leap_frog",
                                        "optimized_velocity_verlet"])
def test_orientations_off_leave_the_trajectory_as_it_is(integrator):
    """Simulation(orientations=False): the same trajectory to the bit (an orientation acts
    on nothing), orientations left as they were; followed, they do turn."""
    runs = {}
    for followed in (True, False):
        sim = _settling()
        sim = gd.Simulation(sim.state, sim.materials, sim.model, walls=sim.walls,
                            skin=0.2 * R, integrator=integrator, orientations=followed)
        start = sim.state.orientations.copy()
        sim.run(steps=1500)
        runs[followed] = sim
    on, off = runs[True].state, runs[False].state
    for name in ("positions", "velocities", "angular_velocities"):
        np.testing.assert_array_equal(getattr(off, name), getattr(on, name))
    assert np.abs(on.angular_velocities).max() > 1.0
    np.testing.assert_array_equal(off.orientations, start)
    assert np.abs(on.orientations - start).max() > 1e-3


def test_capacity_overflow_gives_identical_run():
    steps = 4000
    normal = _settling()
    normal.run(steps=steps)
    assert int(normal.pairs.start[normal.state.n]) > 1

    grown = _settling()
    grown._allocate_pairs(1)
    grown._allocate_walls(1)
    sizes = []
    grown.run(steps=steps, every=[(gd.Periodic(steps=50),
                                   lambda s: sizes.append(s.pairs.partners.size))])
    assert grown.pairs.partners.size > 1 and grown.wall_pairs.ids.size > 1
    for name in ("positions", "velocities", "angular_velocities", "orientations", "forces"):
        np.testing.assert_array_equal(getattr(grown.state, name), getattr(normal.state, name))
    assert grown.rebuilds == normal.rebuilds
    m = int(normal.pairs.start[normal.state.n])
    np.testing.assert_array_equal(grown.pairs.start, normal.pairs.start)
    np.testing.assert_array_equal(grown.pairs.partners[:m], normal.pairs.partners[:m])
    np.testing.assert_array_equal(grown.pairs.history[:m], normal.pairs.history[:m])
    assert np.any(grown.pairs.history[:m] != 0.0)        # springs were loaded


def test_capacity_growth_mid_run_keeps_history():
    """Storage that fits the first build but not a later one grows mid-run (during
    settling the pair count rises), carrying every contact's spring over."""
    steps = 4000
    normal = _settling()
    normal.run(steps=1)
    first = int(normal.pairs.start[normal.state.n])
    normal.run(steps=steps - 1)

    grown = _settling()
    grown._allocate_pairs(first)
    sizes = []
    grown.run(steps=steps, every=[(gd.Periodic(steps=10),
                                   lambda s: sizes.append(s.pairs.partners.size))])
    assert sizes[0] == first and sizes[-1] > first, "no growth happened mid-run"
    for name in ("positions", "velocities", "angular_velocities"):
        np.testing.assert_array_equal(getattr(grown.state, name), getattr(normal.state, name))


# ---------------------------------------------------------------- 3. force gather
@pytest.mark.parametrize("dim,periodic", [(3, False), (3, True), (2, False)])
def test_force_gather_matches_naive_sum(dim, periodic):
    rng = np.random.default_rng(7)
    n = 400 if dim == 3 else 300
    radii = rng.uniform(0.5 * R, 1.5 * R, n)
    radii[: n // 5] *= 2.5                                # a few big ones: 7.5:1
    pos, length = lattice(n, 1.8 * R, dim, rng, jitter=0.3)   # many overlaps
    st = gd.State.create(pos[:, :dim] if dim == 2 else pos, radii, RHO, dim=dim)
    gravity = (0.3, -9.81, 0.0) if dim == 2 else (0.3, -0.4, -9.81)
    kwargs = {}
    if periodic:
        length = max(length, 2 * (2 * radii.max() + 0.2 * R) + 1e-9)
        kwargs["periodic"] = [gd.PeriodicBoundary(a, -0.5 * length, 0.5 * length)
                              for a in range(dim)]
    sim = gd.Simulation(st, [hooke_material()], gd.ContactModel("hooke"), gravity=gravity,
                        skin=0.2 * R, overlap_limit=1e9, **kwargs)
    sim.run(steps=1)
    expect, scale = naive.hooke_forces(st.positions, st.radii, st.masses, KN, gravity,
                                       lengths_of(sim))
    touching = len(naive.touching_pairs(st.positions, st.radii, lengths_of(sim)))
    assert touching > n                                   # a dense, overlapping cloud
    err = np.abs(st.forces - expect).max(axis=1) / scale
    assert err.max() < 1e-12, err.max()
    assert np.all(st.torques == 0.0)                      # frictionless: no torque
    # per-pair forces of contacts() against the same law
    c = sim.contacts()
    i, j = c.i, c.j
    d = naive.min_image(st.positions[i] - st.positions[j], lengths_of(sim))
    dist = np.linalg.norm(d, axis=1)
    fp = (KN * (st.radii[i] + st.radii[j] - dist) / dist)[:, None] * d
    np.testing.assert_allclose(c.force, fp, rtol=1e-12, atol=1e-12 * np.abs(fp).max())


# --------------------------------------------------- 4. contact history over rebuilds
def _pocket(skin, tilt=0.25, seed=5):
    """A free sphere (3) in the pocket of three fixed spheres (0, 1, 2) under tilted
    gravity, held by its tangential springs, and six bystanders flying away fast."""
    rng = np.random.default_rng(seed)
    side = 2.2 * R
    base = np.array([[0, 0, 0], [side, 0, 0], [side / 2, side * np.sqrt(3) / 2, 0]])
    centre = base.mean(axis=0)
    height = np.sqrt((2 * R) ** 2 - (side / np.sqrt(3)) ** 2)
    top = centre + [0, 0, height]
    far = []
    vel = []
    for k in range(6):
        u = rng.normal(size=3)
        u /= np.linalg.norm(u)
        far.append(centre + 15 * R * u)
        vel.append(0.8 * u)
    pos = np.vstack([base, top, far])
    v = np.vstack([np.zeros((4, 3)), vel])
    st = gd.State.create(pos, np.full(10, R), RHO, velocities=v)
    st.fixed[:3] = 1
    model = gd.ContactModel("hooke", "linear", "cundall_strack")
    mat = hooke_material(friction=0.8, kt=2.0 / 7.0 * KN, restitution=0.3)
    g = 9.81 * np.array([np.sin(tilt), 0.3 * np.sin(tilt), -np.cos(tilt)])
    return gd.Simulation(st, [mat], model, gravity=g, skin=skin)


def _pocket_run(skin, steps=3000, spoil_at=None):
    sim = _pocket(skin)
    record = []

    def cb(s):
        hist = []
        for i in range(3):
            k = pair_index(s, i, 3)
            assert k >= 0
            hist.append(s.pairs.history[k, :3].copy())
        record.append(np.concatenate(hist))
        if spoil_at is not None and s.step == spoil_at:
            s.pairs.history[:] = 0.0                   # what a lost history does

    sim.run(steps=steps, every=[(gd.Periodic(steps=25), cb)])
    return sim, np.array(record)


def test_history_is_carried_across_rebuilds():
    huge, rec_huge = _pocket_run(skin=100 * R)
    small, rec_small = _pocket_run(skin=0.05 * R)
    assert huge.rebuilds == 1
    assert small.rebuilds >= 50, small.rebuilds
    scale = np.abs(rec_huge).max()
    assert scale > 1e-8                                   # the springs hold a real load
    np.testing.assert_allclose(rec_small, rec_huge, rtol=0, atol=1e-12 * scale)
    for name in ("positions", "velocities", "angular_velocities"):
        a, b = getattr(small.state, name), getattr(huge.state, name)
        np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12 * np.abs(b).max())
    # the comparison can fail: a history dropped once moves the grain measurably
    spoiled, _ = _pocket_run(skin=100 * R, spoil_at=1500)
    moved = np.abs(spoiled.state.positions[3] - huge.state.positions[3]).max()
    assert moved > 1e-9, moved


# ------------------------------------------------------------- 5. momentum
def test_momentum_conserved_free_gas():
    rng = np.random.default_rng(11)
    n = 216
    radii = rng.uniform(0.6 * R, 1.4 * R, n)
    pos, length = lattice(n, 2.9 * R, 3, rng, jitter=0.1)
    pos -= 0.3 * length                                     # origin off-centre
    v = random_velocities(n, 3, 0.6, rng) + [0.3, -0.2, 0.1]
    st = gd.State.create(pos, radii, RHO, velocities=v)
    st.angular_velocities[:] = rng.normal(0.0, 300.0, (n, 3))
    mat = gd.Material(density=RHO, restitution=0.6, friction_sliding=0.5,
                      friction_static=0.5, tangential_damping=0.5)
    sim = gd.Simulation(st, [mat], gd.ContactModel("hertz", "tsuji", "mindlin"),
                        gravity=(0.0, 0.0, 0.0))
    p0, _ = naive.linear_momentum(st.masses, st.velocities)
    l0, _ = naive.angular_momentum(st.masses, st.inertias, st.positions, st.velocities,
                                   st.angular_velocities)
    worst = {"p": 0.0, "l": 0.0}

    def cb(s):
        p, ps = naive.linear_momentum(st.masses, st.velocities)
        l, ls = naive.angular_momentum(st.masses, st.inertias, st.positions, st.velocities,
                                       st.angular_velocities)
        worst["p"] = max(worst["p"], np.abs(p - p0).max() / ps)
        worst["l"] = max(worst["l"], np.abs(l - l0).max() / ls)

    sim.run(steps=3000, every=[(gd.Periodic(steps=100), cb)])
    diss = sim.dissipated
    assert diss["normal"] > 0 and diss["tangential"] > 0    # damped, frictional collisions
    print(f"momentum: linear {worst['p']:.2e}, angular {worst['l']:.2e} (relative)")
    assert worst["p"] < 1e-12
    assert worst["l"] < 1e-10


# ------------------------------------------------------------- 6. energy, dt^2
def _elastic_gas(dt, seed=15):
    rng = np.random.default_rng(seed)
    n = 64
    radii = rng.uniform(0.8 * R, 1.2 * R, n)
    pos, length = lattice(n, 2.6 * R, 3, rng, jitter=0.1)
    st = gd.State.create(pos, radii, RHO, velocities=random_velocities(n, 3, 1.0, rng))
    mat = gd.Material(density=RHO, youngs_modulus=1e8, poisson_ratio=0.3)
    return gd.Simulation(st, [mat], gd.ContactModel("hertz"), gravity=(0.0, 0.0, 0.0),
                         dt=dt, periodic=[gd.PeriodicBoundary(a, 0.0, length)
                                          for a in range(3)])


def _energy(sim):
    st = sim.state
    e_star = sim.params[0, 0, COL["youngs_eff"]]
    return naive.kinetic_energy(st.masses, st.inertias, st.velocities,
                                st.angular_velocities) + \
        naive.hertz_energy(st.positions, st.radii, e_star, lengths_of(sim))


def test_elastic_energy_of_a_pair_matches_graindyn():
    sim = _elastic_gas(None)
    sim.run(steps=300)
    st = sim.state
    i, j, d, r2 = naive.separations(st.positions, lengths_of(sim))
    rsum = st.radii[i] + st.radii[j]
    on = np.nonzero(r2 < rsum**2)[0]
    assert on.size > 0
    e_star = sim.params[0, 0, COL["youngs_eff"]]
    hist = np.zeros((1, 3))
    for k in on:
        a, b = st.radii[i[k]], st.radii[j[k]]
        h = a + b - np.sqrt(r2[k])
        ours = 8.0 / 15.0 * e_star * np.sqrt(a * b / (a + b)) * h**2.5
        theirs = contact_energy(sim.model_ids, sim.params, 0, 0, h, a * b / (a + b), hist, 0)
        assert theirs == pytest.approx(ours, rel=1e-12)


def test_energy_drift_scales_as_dt_squared():
    """max |E - E0| over the same sample times for dt, dt/2, dt/4 (dt = 0.1 T_R).  The
    gas is chaotic, so the window is kept short (about 100 T_R, a few collisions per
    grain); with longer windows or other seeds the ratios scatter around 4 (2..6)."""
    dt0 = 0.5 * _elastic_gas(None).dt                     # 0.1 of the Rayleigh time
    total = 1000                                          # steps at dt0
    drifts = []
    for f in (1, 2, 4):
        sim = _elastic_gas(dt0 / f)
        e0 = _energy(sim)
        errs = []
        sim.run(steps=total * f, every=[(gd.Periodic(steps=2 * f),
                                         lambda s: errs.append(abs(_energy(s) - e0)))])
        drifts.append(max(errs) / e0)
    ratios = [drifts[0] / drifts[1], drifts[1] / drifts[2]]
    print(f"energy drift {drifts}, ratios {ratios}")
    assert drifts[0] < 1e-3
    for r in ratios:
        assert 3.2 < r < 4.8, (drifts, ratios)


# ------------------------------------------------------------- 7. determinism
def test_same_run_twice_is_bit_identical():
    def once():
        rng = np.random.default_rng(17)
        n = 300
        radii = rng.uniform(0.5 * R, 1.5 * R, n)
        pos, length = lattice(n, 2.1 * radii.max(), 3, rng, jitter=0.02)
        st = gd.State.create(pos, radii, RHO, velocities=random_velocities(n, 3, 0.5, rng))
        mat = gd.Material(density=RHO, restitution=0.7, friction_sliding=0.4,
                          friction_static=0.4)
        sim = gd.Simulation(st, [mat], gd.ContactModel("hertz", "tsuji", "mindlin"),
                            gravity=(0.0, 0.0, 0.0),
                            periodic=[gd.PeriodicBoundary(a, 0.0, length) for a in range(3)])
        sim.run(steps=1500)
        return sim

    a, b = once(), once()
    for name in ("positions", "velocities", "angular_velocities", "orientations"):
        np.testing.assert_array_equal(getattr(a.state, name), getattr(b.state, name))
    assert a.dissipated == b.dissipated
    # on another thread count the grains are cut into other blocks, which changes the
    # association of the force sums on a grain (contacts._pair_block) and of the energy
    # totals: the same trajectory up to rounding
    if numba.config.NUMBA_NUM_THREADS >= 2:
        before = numba.get_num_threads()
        numba.set_num_threads(2)
        try:
            c = once()
        finally:
            numba.set_num_threads(before)
        for name in ("positions", "velocities", "angular_velocities", "orientations"):
            expected = getattr(a.state, name)
            np.testing.assert_allclose(getattr(c.state, name), expected, rtol=1e-9,
                                       atol=1e-12 * np.abs(expected).max())
        for kind in ("normal", "tangential"):
            assert c.dissipated[kind] == pytest.approx(a.dissipated[kind], rel=1e-12)


# ------------------------------------------------------------- 8. blow-up
def _colliding_pair(dt, allow):
    st = gd.State.create([[0, 0, 0], [2.1 * R, 0, 0]], [R, R], RHO,
                         velocities=[[1.0, 0, 0], [-1.0, 0, 0]])
    mat = gd.Material(density=RHO)
    return gd.Simulation(st, [mat], gd.ContactModel("hertz"), gravity=(0, 0, 0), dt=dt,
                         allow_large_dt=allow)


def test_huge_time_step_raises_simulation_error():
    t_r = _colliding_pair(None, False).dt_report["critical_time_s"]
    sim = _colliding_pair(20 * t_r, True)
    with pytest.raises(gd.SimulationError, match=r"(?i)time step|overlap"):
        sim.run(steps=200)


def test_huge_time_step_raises_when_checked_every_step():
    t_r = _colliding_pair(None, False).dt_report["critical_time_s"]
    st = gd.State.create([[0, 0, 0], [2.1 * R, 0, 0]], [R, R], RHO,
                         velocities=[[1.0, 0, 0], [-1.0, 0, 0]])
    sim = gd.Simulation(st, [gd.Material(density=RHO)], gd.ContactModel("hertz"),
                        gravity=(0, 0, 0), dt=20 * t_r, allow_large_dt=True, check_interval=1)
    with pytest.raises(gd.SimulationError, match=r"(?i)time step|overlap"):
        sim.run(steps=200)


def test_grain_behind_a_wall_is_refused_before_the_first_step():
    """A grain that starts half behind a wall (overlap 1.5 R) stops the run before any
    motion, with the cause, instead of being flung away."""
    st = gd.State.create([[0, 0, -0.5 * R], [0, 0, 3 * R]], [R, R], RHO)
    sim = gd.Simulation(st, [gd.Material(density=RHO)], gd.ContactModel("hertz"),
                        walls=[gd.Plane((0, 0, 0), (0, 0, 1))], gravity=(0, 0, 0))
    with pytest.raises(gd.SimulationError, match="before the first step.*behind a wall"):
        sim.run(steps=10)
    assert sim.step == 0 and sim.state.positions[0, 2] == -0.5 * R


def test_non_finite_position_is_a_simulation_error():
    """A NaN coordinate stops the run with the non-finite message (the neighbour
    rebuild cannot grid it and must not try)."""
    st = gd.State.create([[0, 0, 0], [3 * R, 0, 0]], [R, R], RHO)
    st.positions[1, 0] = np.nan
    sim = gd.Simulation(st, [gd.Material(density=RHO)], gd.ContactModel("hertz"),
                        gravity=(0, 0, 0))
    with pytest.raises(gd.SimulationError, match="non-finite"):
        sim.run(steps=10)


def test_time_step_above_safe_fraction_is_rejected():
    t_r = _colliding_pair(None, False).dt_report["critical_time_s"]
    with pytest.raises(ValueError, match="Rayleigh time"):
        _colliding_pair(0.6 * t_r, False)
    _colliding_pair(0.45 * t_r, False)                    # below the limit: accepted


# ------------------------------------------------------------- 9. 2D
def test_2d_settling_stays_in_plane():
    rng = np.random.default_rng(19)
    n = 200
    radii = rng.uniform(0.6 * R, 1.2 * R, n)
    pos, length = lattice(n, 2.6 * R, 2, rng)
    pos[:, 1] += 2 * R
    st = gd.State.create(pos[:, :2], radii, RHO / 100, dim=2,
                         velocities=random_velocities(n, 2, 0.2, rng)[:, :2])
    st.angular_velocities[:, 2] = rng.normal(0.0, 100.0, n)
    mat = gd.Material(density=RHO / 100, restitution=0.5, friction_sliding=0.5,
                      friction_static=0.5)
    sim = gd.Simulation(st, [mat], gd.ContactModel("hertz", "tsuji", "mindlin"),
                        walls=gd.box((0, 0), (length, 4 * length), dim=2),
                        gravity=(0.0, -9.81, 0.0))

    def check(s):
        assert np.all(st.positions[:, 2] == 0.0)
        assert np.all(st.velocities[:, 2] == 0.0)
        assert np.all(st.forces[:, 2] == 0.0)
        assert np.all(st.angular_velocities[:, :2] == 0.0)
        assert np.all(st.torques[:, :2] == 0.0)
        assert np.all(st.orientations[:, 1:3] == 0.0)

    sim.run(steps=4000, every=[(gd.Periodic(steps=200), check)])
    assert sim.dissipated["tangential"] > 0                # friction was active
    assert np.any(st.angular_velocities[:, 2] != 0.0)


def test_growing_the_pair_lists_mid_step_changes_nothing():
    """A collapsing bed outgrows short pair lists: the loop returns RELIST after
    the step's first drift, the rebuild returns GROW, the arrays grow, and the step
    resumes without drifting again.  The rebuild is due at the same step as in a run with room to spare, so the
    two runs agree to the bit."""
    def column(capacity):
        rng = np.random.default_rng(5)
        grid = (np.arange(6) + 0.5) * 0.65e-3
        pos = np.array([(x, y, z) for x in grid for y in grid for z in grid[:5]])
        pos += rng.uniform(-0.04e-3, 0.04e-3, pos.shape)
        st = gd.State.create(pos, np.full(len(pos), 0.25e-3), RHO)
        sim = gd.Simulation(st, [gd.Material(density=RHO, restitution=0.5)],
                            gd.ContactModel("hertz", "tsuji", "mindlin"),
                            walls=gd.box((0, 0, 0), (3.9e-3, 3.9e-3, 10e-3)))
        if capacity:
            sim._allocate_pairs(capacity)
        start = sim.pairs.partners.size
        sim.run(steps=10000)
        return sim, sim.pairs.partners.size > start

    grown, did_grow = column(64)
    roomy, roomy_grew = column(5000)
    assert did_grow and not roomy_grew
    assert grown.rebuilds == roomy.rebuilds
    for name in ("positions", "velocities", "angular_velocities"):
        np.testing.assert_array_equal(getattr(grown.state, name), getattr(roomy.state, name))
