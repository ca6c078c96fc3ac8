"""Rolling resistance: torques [N m] on grain i (grain j gets the opposite couple)
from the rolling part w_r = w_t of the relative angular velocity w_i - w_j [rad/s]
(its component in the tangent plane).  Each returns the torque and the energy [J]
dissipated in the step dt [s].  In 2D (disks in the x-y plane) w_r is the z spin
difference, and the same functions give the disk laws.

type A, 'constant' (Ai, Chen, Rotter & Ooi 2011, Powder Technol. 206:269, model A):
    M = -mu_r R* |f_n| w_r/|w_r|;  also Oquendo's rolling couple (Eq. 8-9, see
    physics/contact.py) with mu_r = tan(theta_r) and R* -> R'_ij.
EPSD, 'epsd' (Ai et al. 2011 model C): an elastic-plastic spring-dashpot on the
    relative rolling rotation, k_r = k_roll R*^2 [N m/rad], C_r = gamma_roll R*^2
    [N m s], the spring capped at mu_r R* |f_n| and the dashpot off at the cap.  It is
    the tangential capped spring-dashpot with the rotation in place of the
    displacement: physics.tangential.tangential_spring_force with (k_r, C_r, mu_r R*,
    cap = 2) serves it, history 3 values (the rotation [rad]).
"""
import math

from .._jit import scalar


@scalar
def rolling_constant_torque(limit, wx, wy, wz, dt):
    """Constant-magnitude torque -limit w/|w| opposing the relative rolling w [rad/s]
    (type A); limit = mu_r R |f_n| [N m].  Zero when w = 0."""
    speed = math.sqrt(wx * wx + wy * wy + wz * wz)
    if speed == 0.0:
        return 0.0, 0.0, 0.0, 0.0
    s = -limit / speed
    return s * wx, s * wy, s * wz, limit * speed * dt
