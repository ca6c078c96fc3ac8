"""The contact dynamics engine against the statics and dynamics of rigid grains: rest
on a plane, a column, rolling and sliding on an incline, the three-disk pile at its
friction thresholds, restitution, exact resume and the solver's reports."""
import math

import numpy as np
import pytest

import graindyn as gd
from graindyn.engines import ENGINES, Setup
from graindyn.engines.contact_dynamics.engine import ContactDynamics

R = 1e-3                 # grain radius [m]
DENSITY = 2650.0         # [kg/m^3] (3D), [kg/m^2] (2D)
G = 9.81                 # [m/s^2]
TOLERANCE = 1e-10        # NLGS tolerance of these tests [-]

pytestmark = pytest.mark.usefixtures("one_thread")


def engine(positions, dim=3, walls=None, gravity=None, mu=0.0, restitution=0.1,
           materials=None, wall_material=None, **options):
    """Rigid grains of radius R on the floor (z = 0 in 3D, y = 0 in 2D), of one material
    (friction mu, restitution e) unless ``materials`` is given."""
    state = gd.State.create(np.asarray(positions, float), np.full(len(positions), R),
                            DENSITY, dim=dim)
    up = (0.0, 0.0, 1.0) if dim == 3 else (0.0, 1.0, 0.0)
    if materials is None:
        materials = [gd.Material(restitution=restitution, friction_static=mu,
                                 friction_sliding=mu)]
    floor = gd.Plane((0.0, 0.0, 0.0), up, material=wall_material or 0, name="floor")
    if gravity is None:
        gravity = (0.0, 0.0, -G) if dim == 3 else (0.0, -G, 0.0)
    options = {"dt": 1e-4, "tolerance": TOLERANCE, **options}
    return ContactDynamics(state, materials, walls=[floor] if walls is None else walls,
                           gravity=gravity, **options)


@pytest.mark.parametrize("theta", [0.5, 1.0])
def test_sphere_rests_on_a_plane_with_its_weight(theta):
    """A sphere at rest on a plane for 10^4 steps: no interpenetration (the gap stays
    >= -1e-15 R), at rest, the floor's normal force the weight to 1e-9."""
    e = engine([[0.0, 0.0, R]], theta=theta)
    weight = e.state.masses[0] * G
    gaps = []
    for _ in range(10):
        e.run(steps=1000)
        gaps.append(e.state.positions[0, 2] - R)
        c = e.wall_contacts()
        assert c.normal_force.sum() == pytest.approx(weight, rel=1e-9)
    assert min(gaps) >= -1e-15 * R
    assert np.abs(e.state.velocities).max() < 1e-12
    assert e.not_converged == 0 and e.last_residual <= TOLERANCE


@pytest.mark.parametrize("dim", [2, 3])
def test_column_carries_the_weight_above_each_contact(dim):
    """A vertical column of six grains on a floor: the force below grain k is the
    weight of grains k..5 (the solver's tolerance), the floor carries them all."""
    n = 6
    axis = dim - 1
    positions = np.zeros((n, 3))
    positions[:, axis] = R * (1 + 2 * np.arange(n))
    e = engine(positions[:, :dim], dim=dim)
    e.run(steps=20)
    m = e.state.masses[0]
    c = e.contacts()
    below = np.minimum(c.i, c.j)           # the lower grain of each pair is i or j
    upper = np.maximum(c.i, c.j)
    assert sorted(below.tolist()) == list(range(n - 1))
    for k, force in zip(upper, c.normal_force):
        assert force == pytest.approx((n - k) * m * G, rel=1e-8)
    assert e.wall_contacts().normal_force.sum() == pytest.approx(n * m * G, rel=1e-8)
    assert e.walls.normal_force(0) == pytest.approx(n * m * G, rel=1e-8)
    assert e.not_converged == 0


INCLINE = math.radians(20.0)


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("mu", [0.5, 0.05])
def test_grain_on_an_incline_rolls_or_slides(dim, mu):
    """A grain on an incline of 20 degrees (gravity tilted over a level floor): it rolls
    without slipping with a = g sin / (1 + I/(m R^2)) (5/7, 2/3) when mu >= tan / (1 +
    m R^2/I) (2/7 tan, 1/3 tan), otherwise slides with a = g (sin - mu cos) and angular
    acceleration mu g cos m R / I (5 mu g cos/(2R), 2 mu g cos/R)."""
    sin, cos = math.sin(INCLINE), math.cos(INCLINE)
    if dim == 3:
        gravity, start, spin_axis = (G * sin, 0.0, -G * cos), [[0.0, 0.0, R]], 1
    else:
        gravity, start, spin_axis = (G * sin, -G * cos, 0.0), [[0.0, R]], 2
    e = engine(start, dim=dim, gravity=gravity, mu=mu)
    ratio = 0.4 if dim == 3 else 0.5                        # I / (m R^2)
    time = 0.05
    e.run(time=time)
    t = e.time
    acceleration = e.state.velocities[0, 0] / t
    angular = abs(e.state.angular_velocities[0, spin_axis]) / t
    if mu >= tan_threshold(ratio):
        assert acceleration == pytest.approx(G * sin / (1 + ratio), rel=1e-7)
        assert angular == pytest.approx(acceleration / R, rel=1e-7)
    else:
        assert acceleration == pytest.approx(G * (sin - mu * cos), rel=1e-7)
        assert angular == pytest.approx(mu * G * cos / (ratio * R), rel=1e-7)
    assert abs(e.state.positions[0, dim - 1] - R) < 1e-12 * R   # stays on the floor


def tan_threshold(ratio):
    """The least friction for rolling without slipping on the incline: tan / (1 + 1/ratio)."""
    return math.tan(INCLINE) / (1.0 + 1.0 / ratio)


GRAIN_THRESHOLD = 2.0 - math.sqrt(3.0)
FLOOR_THRESHOLD = (2.0 - math.sqrt(3.0)) / 3.0


@pytest.mark.parametrize("mu_grain, mu_floor, stays", [
    (1.02 * GRAIN_THRESHOLD, 1.02 * FLOOR_THRESHOLD, True),
    (0.98 * GRAIN_THRESHOLD, 1.02 * FLOOR_THRESHOLD, False),
    (1.02 * GRAIN_THRESHOLD, 0.98 * FLOOR_THRESHOLD, False),
])
def test_three_disk_pile_stands_at_its_friction_thresholds(mu_grain, mu_floor, stays):
    """Two equal disks touching on a floor and a third on both: statics needs mu_grain
    >= 2 - sqrt(3) and mu_floor >= (2 - sqrt(3))/3.  2 % above both the pile stays at
    rest; 2 % below either, the top disk sinks."""
    # the floor's material mixes with the grains' by the geometric mean: choose it so
    # that the grain-floor coefficient is mu_floor
    grain = gd.Material("grain", restitution=0.1, friction_static=mu_grain,
                        friction_sliding=mu_grain)
    wall = gd.Material("floor", restitution=0.1, friction_static=mu_floor**2 / mu_grain,
                       friction_sliding=mu_floor**2 / mu_grain)
    top = R * (1.0 + math.sqrt(3.0))
    e = engine([[-R, R], [R, R], [0.0, top]], dim=2, materials=[grain, wall],
               wall_material=1)
    e.run(time=0.02)
    sunk = top - e.state.positions[2, 1]
    if stays:
        assert sunk < 1e-12 * R
        assert np.abs(e.state.velocities).max() < 1e-10
    else:
        assert sunk > 1e-3 * R
    assert e.not_converged == 0


@pytest.mark.parametrize("theta", [0.5, 1.0])
def test_dropped_ball_rebounds_to_e_squared_of_its_height(theta):
    """A ball dropped from h = 2 mm above a plane, restitution e = 0.7: after the
    bounce it climbs to e^2 h (1 %: the impact is caught within a step of |u| dt)."""
    h, e_n = 2e-3, 0.7
    e = engine([[0.0, 0.0, R + h]], restitution=e_n, dt=1e-5, theta=theta)
    heights, lost = [], []

    def record(x):
        heights.append(x.state.positions[0, 2] - R)
        lost.append(x.energies()["dissipated_normal"])

    e.run(time=0.045, every=[(gd.Periodic(steps=1), record)])
    heights = np.array(heights)
    bounce = np.argmin(heights)
    assert heights[bounce] < 1e-2 * h
    apex = bounce + np.argmax(heights[bounce:])
    assert heights[apex] == pytest.approx(e_n**2 * h, rel=1e-2)
    assert apex < heights.size - 1                       # the apex, not the run's end
    assert lost[apex] == pytest.approx((1 - e_n**2) * e.state.masses[0] * G * h, rel=1e-2)


def _pile():
    """Twelve rough disks falling into a small box, spinning and colliding."""
    rng = np.random.default_rng(7)
    grid = np.stack(np.meshgrid(np.arange(4), np.arange(3)), -1).reshape(-1, 2)
    positions = (grid + 0.5) * 2.2 * R + rng.uniform(-0.05 * R, 0.05 * R, grid.shape)
    walls = gd.box((0.0, 0.0), (8.8 * R, 20 * R), dim=2)
    e = engine(positions, dim=2, walls=walls, mu=0.4, restitution=0.3, tolerance=1e-6)
    e.state.velocities[:, :2] = rng.normal(0.0, 0.02, (len(positions), 2))
    return e


def test_snapshot_and_restore_resume_to_the_bit():
    """Run a pile, snapshot, run on; restore and run as long again: every array ends
    the same to the bit, the impulses of the warm start included."""
    e = _pile()
    e.run(time=0.01)
    saved = e.snapshot()
    assert "lists/impulses" in saved and "lists/wall_impulses" in saved
    e.run(time=0.02)
    first = e.snapshot()
    again = _pile()
    again.restore(saved)
    again.run(time=0.02)
    second = again.snapshot()
    assert np.any(first["lists/impulses"] != 0.0)
    for name in first:
        np.testing.assert_array_equal(first[name], second[name], err_msg=name)


def test_a_snapshot_of_three_column_impulses_restores_with_zero_couples():
    """A snapshot written before rolling resistance (impulses of 3 columns, no couple)
    restores: the impulses come back with zero couples and the run goes on as the
    present snapshot's does (the pile has no rolling friction, so no couple arises)."""
    e = _pile()
    e.run(time=0.01)
    saved = e.snapshot()
    assert not np.any(saved["lists/impulses"][:, 3:])
    old = {k: (v[:, :3] if k in ("lists/impulses", "lists/wall_impulses") else v)
           for k, v in saved.items()}
    again, present = _pile(), _pile()
    again.restore(old)
    present.restore(saved)
    np.testing.assert_array_equal(again.lists.impulses, present.lists.impulses)
    again.run(time=0.005)
    present.run(time=0.005)
    np.testing.assert_array_equal(again.state.positions, present.state.positions)


def test_a_step_that_does_not_converge_is_reported():
    """With one NLGS sweep allowed a column cannot converge: the run warns and counts
    the steps (not_converged), the residual above the tolerance."""
    positions = [[0.0, 0.0, R * (1 + 2 * k)] for k in range(6)]
    e = engine(positions, max_iterations=1)
    with pytest.warns(RuntimeWarning, match="did not converge"):
        e.run(steps=10)
    assert e.not_converged > 0 and e.last_residual > TOLERANCE
    assert e.last_iterations == 1


def test_registry_entry_builds_and_checks():
    """ENGINES["contact_dynamics"]: its settings, time-step report and build."""
    entry = ENGINES["contact_dynamics"]
    state = gd.State.create([[0.0, 0.0, R]], [R], DENSITY)
    setup = Setup([gd.Material(restitution=0.5)], None, [gd.Plane((0, 0, 0), (0, 0, 1))],
                  [], (0.0, 0.0, -G), "cpu")
    settings = entry.settings(dt=2e-4, theta=1.0)
    report = entry.check(state, setup, settings)
    assert report["critical_time_s"] == pytest.approx(math.sqrt(R / G))
    assert report["fraction"] == pytest.approx(2e-4 / math.sqrt(R / G))
    built = entry.build(state, setup, settings)
    assert built.dt == 2e-4 and built.theta == 1.0
    with pytest.raises(ValueError, match="engine.dt"):
        entry.check(state, setup, entry.settings(dt=5e-3))


def _rolling(dim, gravity, mu, mu_r, **options):
    start = [[0.0, 0.0, R]] if dim == 3 else [[0.0, R]]
    material = gd.Material(restitution=0.1, friction_static=mu, friction_sliding=mu,
                           friction_rolling=mu_r)
    return engine(start, dim=dim, gravity=gravity, materials=[material], **options)


@pytest.mark.parametrize("dim", [2, 3])
def test_rolling_resistance_stops_a_rolling_grain(dim):
    """A grain rolling on a level floor at v0 (spin v0/R), rolling friction mu_r: the
    couple mu_r R m g against the roll decelerates it at a = mu_r g / (1 + I/(m R^2))
    (5/7 mu_r g, 2/3 mu_r g) without slipping; it stops after v0^2 / (2 a) and stays,
    and its kinetic energy is dissipated by the rolling couple, none by the normal law."""
    mu_r, v0 = 0.05, 0.02
    gravity = (0.0, 0.0, -G) if dim == 3 else (0.0, -G, 0.0)
    e = _rolling(dim, gravity, 0.5, mu_r)
    ratio = 0.4 if dim == 3 else 0.5
    spin_axis, sign = (1, 1.0) if dim == 3 else (2, -1.0)
    e.state.velocities[0, 0] = v0
    e.state.angular_velocities[0, spin_axis] = sign * v0 / R
    kinetic = 0.5 * e.state.masses[0] * v0**2 * (1 + ratio)
    a = mu_r * G / (1 + ratio)
    e.run(time=0.02)
    assert e.state.velocities[0, 0] == pytest.approx(v0 - a * e.time, rel=1e-9)
    assert sign * e.state.angular_velocities[0, spin_axis] * R == pytest.approx(
        e.state.velocities[0, 0], rel=1e-9)
    e.run(time=v0 / a)
    assert abs(e.state.velocities[0, 0]) < 1e-12 and \
        abs(e.state.angular_velocities[0, spin_axis]) < 1e-9
    assert e.state.positions[0, 0] == pytest.approx(v0**2 / (2 * a), rel=1e-3)
    energies = e.energies()
    assert energies["dissipated_tangential"] == pytest.approx(kinetic, rel=1e-9)
    assert abs(energies["dissipated_normal"]) < 1e-9 * kinetic


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("mu_r", [0.5, 0.1])
def test_rolling_resistance_holds_or_slows_a_grain_on_an_incline(dim, mu_r):
    """A grain on the 20 degree incline with ample sliding friction: held at rest when
    mu_r >= tan (0.364); otherwise it rolls without slipping with
    a = g (sin - mu_r cos) / (1 + I/(m R^2))."""
    sin, cos = math.sin(INCLINE), math.cos(INCLINE)
    gravity = (G * sin, 0.0, -G * cos) if dim == 3 else (G * sin, -G * cos, 0.0)
    e = _rolling(dim, gravity, 0.9, mu_r)
    ratio = 0.4 if dim == 3 else 0.5
    e.run(time=0.05)
    if mu_r >= math.tan(INCLINE):
        assert np.abs(e.state.velocities).max() < 1e-12
        assert np.abs(e.state.angular_velocities).max() < 1e-9
    else:
        acceleration = e.state.velocities[0, 0] / e.time
        assert acceleration == pytest.approx(G * (sin - mu_r * cos) / (1 + ratio), rel=1e-7)
