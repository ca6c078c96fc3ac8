"""Free flight between collisions and the times of the next events (Pérez Sec. 2: grains
"move freely (or with some easily integrable kinematics) between collisions").

Every grain flies on a parabola in the constant gravity g: r(t) = r + v t + g t^2/2,
v(t) = v + g t, its spin constant.  Two grains feel the same g, so their separation
moves on a straight line and the time they touch is a root of a quadratic; a grain
meets a plane wall that is fixed or moves at constant velocity at a root of a
quadratic too, and the inside of a fixed cylinder parallel to g as well.  Every root
is taken in the form that does not cancel (``falling_gap_time``): for a gap
c + b t + a t^2/2 the first zero reached while the gap closes.

Walls with no closed form (segments, cylinders across g, vibrating planes, walls that
start moving later) are met by conservative advancement (``wall_time``): from a gap s
and a lower bound of its rate of change, the time the bound reaches zero is a time
before which the grain cannot touch, and the search steps there until the gap is below
a tolerance with the grain approaching.  It never steps past a contact, so no grain
ever crosses a wall; a search that has not converged after MAX_STEPS steps schedules a
re-prediction (RECHECK) at the place it reached.
"""
import math

from ..._jit import scalar
from ...core.walls import CYLINDER, FIXED, PLANE, SINUSOID, VELOCITY, wall_distance

INF = math.inf
MAX_STEPS = 64
# what a wall search found
COLLIDE, RECHECK = 0, 1


@scalar
def falling_gap_time(c, b, a):
    """The first time t >= 0 [s] at which the gap c + b t + a t^2/2 (c [m], b [m/s],
    a [m/s^2]) reaches zero while closing (b + a t < 0 there); inf when it never does.
    A gap already closed (c <= 0) that is closing gives 0; one closed and opening gives
    the time it closes again (the later root, or the turning point when it never
    reopens).  The roots are computed without cancellation (2c / (-b + sqrt(.)) for the
    first one)."""
    if a == 0.0:
        if b < 0.0:
            return max(c, 0.0) / -b
        return INF
    disc = b * b - 2.0 * a * c
    if c <= 0.0:
        if b < 0.0:
            return 0.0
        if a >= 0.0:
            return INF
        if disc <= 0.0:            # never reopens: it starts closing at the turning point
            return -b / a
        return (b + math.sqrt(disc)) / -a
    if disc < 0.0:
        return INF
    if b < 0.0:
        return 2.0 * c / (-b + math.sqrt(disc))
    if a >= 0.0:
        return INF
    return (b + math.sqrt(disc)) / -a


@scalar
def pair_time(dx, dy, dz, ux, uy, uz, reach):
    """The time [s] until two grains at separation (dx, dy, dz) [m] (r_i - r_j) with
    relative velocity (ux, uy, uz) [m/s] come within ``reach`` = R_i + R_j [m] while
    approaching; 0 when they touch or overlap and approach, inf when they do not meet.
    The separation moves on a straight line (the same gravity on both): the first root
    of |d + u t|^2 = reach^2, as c / (-b + sqrt(b^2 - a c))."""
    b = dx * ux + dy * uy + dz * uz
    if b >= 0.0:
        return INF
    c = dx * dx + dy * dy + dz * dz - reach * reach
    if c <= 0.0:
        return 0.0
    a = ux * ux + uy * uy + uz * uz
    disc = b * b - a * c
    if disc < 0.0:
        return INF
    return c / (-b + math.sqrt(disc))


@scalar
def wall_displacement(motion_kind, motion, w, t):
    """How far wall w has moved from its reference place ``base`` at time t [s], and its
    velocity then: (dx, dy, dz [m], vx, vy, vz [m/s]) for fixed (0), "velocity" and
    "sinusoid" motion (core.walls.Motion), from the motion's start on."""
    kind = motion_kind[w]
    since = t - motion[w, 7]
    if since <= 0.0 or (kind != VELOCITY and kind != SINUSOID):
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    if kind == VELOCITY:
        s = motion[w, 3]
        return (motion[w, 0] * s * since, motion[w, 1] * s * since,
                motion[w, 2] * s * since, motion[w, 0] * s, motion[w, 1] * s,
                motion[w, 2] * s)
    omega = 2.0 * math.pi * motion[w, 5]
    arg = omega * since + motion[w, 6]
    x = motion[w, 4] * (math.sin(arg) - math.sin(motion[w, 6]))
    v = motion[w, 4] * omega * math.cos(arg)
    return (motion[w, 0] * x, motion[w, 1] * x, motion[w, 2] * x, motion[w, 0] * v,
            motion[w, 1] * v, motion[w, 2] * v)


@scalar
def wall_gap(kind, geometry, base, motion_kind, motion, w, t, x, y, z, radius):
    """The gap [m] between a grain of ``radius`` at (x, y, z) and wall w at time t, the
    unit normal from the wall to the grain and the wall's velocity then:
    (gap, nx, ny, nz, vx, vy, vz)."""
    dx, dy, dz, vx, vy, vz = wall_displacement(motion_kind, motion, w, t)
    d, nx, ny, nz = wall_distance(kind, geometry, base, w, x - dx, y - dy, z - dz)
    return d - radius, nx, ny, nz, vx, vy, vz


@scalar
def wall_time(kind, geometry, base, motion_kind, motion, w, now, x, y, z, vx, vy, vz,
              gx, gy, gz, radius, tolerance, horizon):
    """The time [s] from ``now`` until a grain (centre (x, y, z) [m], velocity
    (vx, vy, vz) [m/s] at ``now``, gravity (gx, gy, gz)) touches wall w approaching it,
    looked for up to ``horizon`` [s] from now: (time, COLLIDE or RECHECK), inf beyond the
    horizon.  Closed forms for planes fixed or at constant velocity (started) and for a
    fixed cylinder along g; conservative advancement otherwise (module docstring), with
    gap'' >= n.g - A w^2 |n.u| on a vibrating plane and |gap'| <= |v(t)| + |v_wall| on
    the others, aiming at a gap of ``tolerance`` [m]; a gap below two tolerances with
    the grain approaching counts as a contact."""
    mk = motion_kind[w]
    started = motion[w, 7] <= now
    if kind[w] == PLANE and (mk == FIXED or (mk == VELOCITY and started)):
        g, nx, ny, nz, wx, wy, wz = wall_gap(kind, geometry, base, motion_kind, motion,
                                             w, now, x, y, z, radius)
        t = falling_gap_time(g, nx * (vx - wx) + ny * (vy - wy)
                             + nz * (vz - wz), nx * gx + ny * gy + nz * gz)
        return (t, COLLIDE) if t <= horizon else (INF, COLLIDE)
    ax = geometry[w, 3]
    ay = geometry[w, 4]
    az = geometry[w, 5]
    if kind[w] == CYLINDER and mk == FIXED:
        ga = gx * ax + gy * ay + gz * az
        if abs(gx - ga * ax) + abs(gy - ga * ay) + abs(gz - ga * az) \
                <= 1e-12 * (abs(gx) + abs(gy) + abs(gz)):
            px = x - geometry[w, 0] - base[w, 0]
            py = y - geometry[w, 1] - base[w, 1]
            pz = z - geometry[w, 2] - base[w, 2]
            pa = px * ax + py * ay + pz * az
            va = vx * ax + vy * ay + vz * az
            px -= pa * ax
            py -= pa * ay
            pz -= pa * az
            ux = vx - va * ax
            uy = vy - va * ay
            uz = vz - va * az
            room = geometry[w, 6] - radius
            # room^2 - rho(t)^2 closes as the grain nears the wall: a quadratic in t
            t = falling_gap_time(room * room - (px * px + py * py + pz * pz),
                                 -2.0 * (px * ux + py * uy + pz * uz),
                                 -2.0 * (ux * ux + uy * uy + uz * uz))
            return (t, COLLIDE) if t <= horizon else (INF, COLLIDE)
    # conservative advancement
    wall_speed = 0.0
    wall_acceleration = 0.0
    if mk == VELOCITY:
        wall_speed = abs(motion[w, 3])
    elif mk == SINUSOID:
        omega = 2.0 * math.pi * motion[w, 5]
        wall_speed = abs(motion[w, 4]) * omega
        wall_acceleration = wall_speed * omega
    g_size = math.sqrt(gx * gx + gy * gy + gz * gz)
    t = 0.0
    for _ in range(MAX_STEPS):
        px = x + vx * t + 0.5 * gx * t * t
        py = y + vy * t + 0.5 * gy * t * t
        pz = z + vz * t + 0.5 * gz * t * t
        ux = vx + gx * t
        uy = vy + gy * t
        uz = vz + gz * t
        g, nx, ny, nz, wx, wy, wz = wall_gap(kind, geometry, base, motion_kind, motion,
                                             w, now + t, px, py, pz, radius)
        rate = nx * (ux - wx) + ny * (uy - wy) + nz * (uz - wz)
        # the steps aim at a gap of one tolerance: within two it is a contact
        if g <= 2.0 * tolerance and rate < 0.0:
            return t, COLLIDE
        bound_speed = math.sqrt(ux * ux + uy * uy + uz * uz) + wall_speed
        if kind[w] == PLANE:
            along = abs(nx * motion[w, 0] + ny * motion[w, 1] + nz * motion[w, 2])
            s = falling_gap_time(g - tolerance, rate,
                                 nx * gx + ny * gy + nz * gz - wall_acceleration * along)
        else:
            s = falling_gap_time(g - tolerance, -bound_speed, -g_size)
        if g <= tolerance:         # touching and not approaching: move on past it
            s = max(s, tolerance / (bound_speed + 1e-300))
        t += s
        if t > horizon:
            return INF, COLLIDE
    return t, RECHECK


@scalar
def boundary_time(x, v, g, lower, upper):
    """The time [s] until a coordinate x [m] moving at v [m/s] with acceleration g
    [m/s^2] leaves [lower, upper] (either may be infinite), and through which side:
    (time, 1 for upper, 0 for lower)."""
    t_up = falling_gap_time(upper - x, -v, -g) if upper < INF else INF
    t_down = falling_gap_time(x - lower, v, g) if lower > -INF else INF
    if t_up <= t_down:
        return t_up, 1
    return t_down, 0
