"""One oblique impact of two spheres, in graindyn and in LAMMPS, side by side (issue 4:
Hertz-Mindlin against `pair granular hertz/material ... tangential mindlin`).

    python comparisons/lammps_oblique_impact.py [LMP]      (LMP: the LAMMPS binary, lmp)

Sphere d = 1 mm, rho = 2650 kg/m^3, E = 1e8 Pa, nu = 0.3, restitution 0.9 (Tsuji
damping), Mindlin tangential spring kt = 8 G* a with tangential damping ratio 1 and
Coulomb cap mu = 0.5, no gravity.  Sphere 1 above sphere 2 along z, velocities
+-(vt/2, 0, -vn/2): relative normal speed vn = 1 m/s, relative tangential speed
vt = vn tan(theta) along x, no spin; dt = 5e-8 s (about 1000 steps per
contact, 3.6e-5 s), plain velocity Verlet in both codes.  Reported for sphere 1: the
normal restitution vz'/vz, the tangential ratio vx'/vx and the spin R wy'/vx.

Tsuji damping: graindyn follows the current LAMMPS source, c = sqrt(2) alpha(e)
sqrt(m* k); LAMMPS releases before that change (Debian's 29 Sep 2021 among them) use
c = alpha(e) sqrt(m* k), which gives restitution 0.929 for e = 0.9.  So LAMMPS is run
twice: with e as given ("LMP e") and with the e' for which its damping coefficient
equals graindyn's, alpha(e') = sqrt(2) alpha(e) ("LMP e'": same normal and tangential
dashpots, the like-for-like comparison).  Prints, for each angle, the normal
restitution -vz'/vn, the tangential ratio vx'/vx and the spin R wy'/vx of both codes,
for `mindlin` and `mindlin_rescale` (graindyn's mindlin rescales the spring when the
contact shrinks, Elata-Berryman; LAMMPS's plain mindlin does not).
"""
import pathlib
import subprocess
import sys
import tempfile

import numpy as np

R, RHO, E, NU, REST, MU, VN, DT, STEPS = 0.5e-3, 2650.0, 1e8, 0.3, 0.9, 0.5, 1.0, 5e-8, 2000
TANGENTS = (0.1, 0.3, 0.6, 1.0, 2.0, 4.0)

LAMMPS_INPUT = """units si
atom_style sphere
atom_modify map array
boundary f f f
comm_modify vel yes
region box block -0.01 0.01 -0.01 0.01 -0.01 0.01
create_box 1 box
create_atoms 1 single 0 0 {z0}
create_atoms 1 single 0 0 -{z0}
set atom * diameter {d} density {rho}
group one id 1
group two id 2
velocity one set {vt} 0 {vz}
velocity two set {mvt} 0 {mvz}
neighbor 1e-4 bin
variable gm string "hertz/material {E} {e} {nu} tangential {tangential} NULL 1.0 {mu} damping tsuji"
pair_style granular
pair_coeff * * ${{gm}}
fix integ all nve/sphere
timestep {dt}
compute om all property/atom omegay
variable vx1 equal vx[1]
variable vz1 equal vz[1]
variable wy1 equal c_om[1]
thermo_style custom step v_vx1 v_vz1 v_wy1
thermo {steps}
run {steps}
print "RESULT $(v_vx1:%.12e) $(v_vz1:%.12e) $(v_wy1:%.12e)"
"""


def old_lammps_restitution():
    """e' with alpha(e') = sqrt(2) alpha(REST): the input that gives a LAMMPS release
    without the sqrt(2) graindyn's Tsuji dashpot."""
    from scipy.optimize import brentq

    from graindyn.physics.reference import tsuji_alpha

    target = 2.0**0.5 * tsuji_alpha(REST)
    return brentq(lambda e: tsuji_alpha(e) - target, 0.05, REST)


def lammps(lmp, vt, tangential, restitution=REST):
    """(vx', vz', wy') of sphere 1 after the impact, from LAMMPS."""
    text = LAMMPS_INPUT.format(z0=R + 1e-7, d=2 * R, rho=RHO, vt=vt / 2, vz=-VN / 2,
                               mvt=-vt / 2, mvz=VN / 2, E=E, e=restitution,
                               nu=NU, mu=MU, dt=DT, steps=STEPS, tangential=tangential)
    with tempfile.TemporaryDirectory() as tmp:
        path = pathlib.Path(tmp) / "in.oblique"
        path.write_text(text)
        out = subprocess.run([lmp, "-in", str(path), "-log", "none"], capture_output=True,
                             text=True, cwd=tmp)
    lines = [line for line in out.stdout.splitlines() if line.startswith("RESULT")]
    if not lines:
        sys.exit(f"LAMMPS failed:\n{out.stdout[-2000:]}\n{out.stderr[-2000:]}")
    line = lines[0]
    return np.array(line.split()[1:], dtype=float)


def graindyn(vt):
    """(vx', vz', wy') of sphere 1 after the impact, from graindyn."""
    import graindyn as gd

    state = gd.State.create(np.array([[0.0, 0.0, R + 1e-7], [0.0, 0.0, -R - 1e-7]]),
                            np.full(2, R), RHO,
                            velocities=np.array([[vt / 2, 0.0, -VN / 2], [-vt / 2, 0.0, VN / 2]]))
    material = gd.Material(density=RHO, youngs_modulus=E, poisson_ratio=NU, restitution=REST,
                           friction_sliding=MU, tangential_damping=1.0)
    sim = gd.Simulation(state, [material], gd.ContactModel("hertz", "tsuji", "mindlin",
                                                           limit_damping=False),
                        gravity=(0.0, 0.0, 0.0),
                        dt=DT, integrator="velocity_verlet_plain", allow_large_dt=True)
    sim.run(steps=STEPS)
    return np.array([state.velocities[0, 0], state.velocities[0, 2],
                     state.angular_velocities[0, 1]])


def ratios(v, vt):
    """normal restitution, tangential ratio, spin ratio of sphere 1."""
    return 2 * v[1] / VN, 2 * v[0] / vt, 2 * R * v[2] / vt


def main(argv):
    lmp = argv[0] if argv else "lmp"
    e_old = old_lammps_restitution()
    runs = [("LMP e " + law, law, REST) for law in ("mindlin_rescale/force",)]
    runs += [("LMP e' " + law, law, e_old) for law in ("mindlin", "mindlin_rescale",
                                                         "mindlin/force", "mindlin_rescale/force")]
    print(f"e = {REST}, e' = {e_old:.6f}")
    print(f"{'tan':>5} {'code':>28} {'e_n':>9} {'vx/vx0':>9} {'R wy/vx0':>9}")
    for tan in TANGENTS:
        vt = VN * tan
        rows = [("graindyn", graindyn(vt))]
        rows += [(name, lammps(lmp, vt, law, e)) for name, law, e in runs]
        for name, v in rows:
            print(f"{tan:5.2f} {name:>28} " + " ".join(f"{x:9.6f}" for x in ratios(v, vt)))


if __name__ == "__main__":
    main(sys.argv[1:])
