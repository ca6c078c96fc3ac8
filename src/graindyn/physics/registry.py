"""The one table of contact laws.

Every law belongs to a mode (normal, damping, tangential, rolling, twisting), has an
integer id (its position in its mode's list: generated here, never written twice),
the pair-table columns it reads, and the number of history values it keeps per
contact.  A contact's history row holds the chosen laws' values one after the other
in the order of ``HISTORY_ORDER``; ``history_layout`` gives each mode its offset.  The pair-parameter table ``params[material_i, material_j, column]`` has the
columns of ``COLUMNS``; kernels index it with the integer constants of ``COL``.

To add a law: write its scalar function in physics/<mode>.py, add a row below, add a
branch in physics/contact.py, and an analytic test.  The compile cache needs no
clearing: its folder is named by a hash of the engine source (_jit.py), and
``graindyn cache clear`` removes the folders left by earlier versions.
"""
from dataclasses import dataclass

MODES = ("normal", "damping", "tangential", "rolling", "twisting")


@dataclass(frozen=True)
class Column:
    """One pair-table column: name, unit, inclusive bounds and meaning."""

    name: str
    unit: str
    lo: float
    hi: float
    doc: str


@dataclass(frozen=True)
class Law:
    """A sub-model: mode, registry key, columns read, history size, reference."""

    mode: str
    name: str
    columns: tuple[str, ...]
    history: int
    reference: str


COLUMNS = (
    Column("kn", "N/m", 0.0, 1e15, "linear normal stiffness"),
    Column("youngs_eff", "Pa", 0.0, 1e15, "effective modulus E*, 1/E* = sum (1-nu^2)/E"),
    Column("shear_eff", "Pa", 0.0, 1e15, "effective shear modulus G*, 1/G* = sum (2-nu)/G"),
    Column("damping_ratio", "-", 0.0, 1e6, "gamma/omega0 of the linear dashpot"),
    Column("damping_constant", "kg/s", 0.0, 1e15, "linear dashpot constant Gamma"),
    Column("gamma_n", "1/(s m^0.5)", 0.0, 1e15, "viscoelastic Hertz damping (Oquendo Eq. 1)"),
    Column("tsuji_alpha", "-", 0.0, 10.0, "Tsuji damping prefactor alpha(e)"),
    Column("kt", "N/m", 0.0, 1e15, "tangential spring stiffness (Cundall-Strack)"),
    Column("tangential_damping", "-", 0.0, 1e6, "tangential/normal damping coefficient ratio"),
    Column("friction_sliding", "-", 0.0, 10.0, "sliding (dynamic) friction coefficient mu_d"),
    Column("friction_static", "-", 0.0, 10.0, "static friction coefficient mu_s"),
    Column("friction_rolling", "-", 0.0, 10.0, "rolling friction coefficient"),
    Column("restitution", "-", 0.0, 1.0, "normal restitution coefficient (input)"),
    Column("slip_threshold", "m/s", 0.0, 1e3,
           "contact-point speed below which Oquendo's grains stick or roll (Eq. 4, 7)"),
    Column("gamma_nt", "1/s", 0.0, 1e15, "Oquendo twisting damping (Eq. 2)"),
    Column("alpha_n", "-", 0.0, 1e3, "Karrech normal dissipation coefficient (Eq. 7)"),
    Column("alpha_t", "-", 0.0, 1e3, "Karrech tangential dissipation coefficient (Eq. 7)"),
    Column("rolling_stiffness", "N/m", 0.0, 1e15,
           "EPSD rolling spring k_roll; torque stiffness k_roll R*^2 [N m/rad]"),
    Column("rolling_damping", "kg/s", 0.0, 1e15,
           "EPSD rolling dashpot gamma_roll; torque damping gamma_roll R*^2 [N m s]"),
    Column("friction_twisting", "-", 0.0, 10.0,
           "twisting friction coefficient: limit torque mu_tw a |f_n|, a = sqrt(R* xi)"),
    Column("twisting_stiffness", "N m/rad", 0.0, 1e15, "EPSD twisting spring"),
    Column("twisting_damping", "N m s", 0.0, 1e15, "EPSD twisting dashpot"),
    Column("inertia_ratio", "-", 0.0, 1.0,
           "I/(m R^2) of the grains' shape, 2/5 spheres, 1/2 disks (Oquendo Eq. 8-9); "
           "set from the dimension, not mixed"),
)
COL = {c.name: k for k, c in enumerate(COLUMNS)}
NCOL = len(COLUMNS)

LAWS = (
    Law("normal", "hooke", ("kn",), 0, "Perez Eq. 14: f = kn xi"),
    Law("normal", "hertz", ("youngs_eff",), 0, "Perez Eq. 17, Oquendo Eq. 1: f = 4/3 E* sqrt(R*) xi^1.5"),
    Law("normal", "walton_braun", ("kn", "restitution"), 1,
        "Walton & Braun 1986 (Perez Sec. 3.1, Fig. 2a): load kn, unload kn/e^2, plastic"),
    Law("normal", "walton_braun_silo", ("kn", "restitution"), 1,
        "Perez Sec. 3.1 Fig. 2b and Sec. 4: load kn, unload e^2 kn"),
    Law("damping", "none", (), 0, "no normal dissipation"),
    Law("damping", "linear", ("damping_ratio", "damping_constant"), 0,
        "Perez Eq. 14-16: f = Gamma xi', Gamma = 2 beta sqrt(kn m*) + Gamma_0"),
    Law("damping", "viscoelastic", ("gamma_n",), 0,
        "Oquendo Eq. 1, Perez Eq. 17: f = m* gamma_n sqrt(xi) xi'"),
    Law("damping", "tsuji", ("tsuji_alpha",), 0,
        "Tsuji et al. 1992 as in LAMMPS: f = alpha sqrt(m* f_el/xi) xi'"),
    Law("damping", "karrech", ("alpha_n",), 0,
        "Karrech Eq. 7: f = 2 alpha_n sqrt(m* k_n) xi', k_n = df/dxi"),
    Law("tangential", "none", (), 0, "frictionless"),
    Law("tangential", "coulomb", ("friction_sliding",), 0,
        "Perez Eq. 19: f = -mu_d f_n v_t/|v_t|"),
    Law("tangential", "cundall_strack", ("kt", "tangential_damping", "friction_sliding"), 3,
        "Perez Eq. 20-23: capped spring + dashpot (a vector in 3D, a scalar along the "
        "tangent in 2D)"),
    Law("tangential", "mindlin", ("shear_eff", "tangential_damping", "friction_sliding"), 4,
        "Mindlin spring kt = 8 G* sqrt(R* xi) (Karrech Eq. 6), Coulomb cap on spring + "
        "dashpot, Elata-Berryman unloading"),
    Law("tangential", "karrech", ("shear_eff", "alpha_t", "friction_sliding"), 4,
        "Karrech Eq. 6-7: Mindlin spring capped at mu f_n, dashpot 2 alpha_t sqrt(m* kt) "
        "outside the cap, Elata-Berryman unloading"),
    Law("tangential", "oquendo", ("shear_eff", "tangential_damping", "friction_sliding",
                                  "friction_static", "friction_rolling", "slip_threshold"), 7,
        "Oquendo Eq. 4-10: sliding mu_k, rolling tan(theta_r), static mu_s"),
    Law("tangential", "oquendo_literal", ("friction_sliding", "friction_static",
                                          "friction_rolling", "slip_threshold",
                                          "inertia_ratio"), 4,
        "Oquendo Eq. 4-10 read literally: sliding mu_k, or rolling with the force of "
        "Eq. 8, or static friction cancelling the pull (Eq. 10), one at a time"),
    Law("rolling", "none", (), 0, "no rolling resistance"),
    Law("rolling", "constant", ("friction_rolling",), 0,
        "type A (Ai et al. 2011): M = -mu_r R* |f_n| w_r/|w_r|"),
    Law("rolling", "epsd", ("rolling_stiffness", "rolling_damping", "friction_rolling"), 3,
        "elastic-plastic spring-dashpot (Ai et al. 2011 type C): capped at mu_r R* |f_n|"),
    Law("twisting", "none", (), 0, "no twisting resistance"),
    Law("twisting", "oquendo", ("gamma_nt",), 0,
        "Oquendo Eq. 2: M = -4 pi gamma_nt m* R* xi w_n"),
    Law("twisting", "constant", ("friction_twisting",), 0,
        "M = -mu_tw a |f_n| sign(w_n) n, a = sqrt(R* xi)"),
    Law("twisting", "epsd", ("twisting_stiffness", "twisting_damping", "friction_twisting"), 1,
        "elastic-plastic spring-dashpot about n, capped at mu_tw a |f_n|"),
)

# the tangential laws whose spring takes its scalar 2D form for disks (physics.contact,
# tangential.tangential_planar_spring_force)
PLANAR_SPRINGS = ("cundall_strack", "mindlin", "karrech")

# where each mode's history values sit in a contact's history row, first to last
HISTORY_ORDER = ("tangential", "normal", "rolling", "twisting", "damping")


def laws(mode: str) -> tuple[Law, ...]:
    """The laws of one mode, in id order."""
    return tuple(law for law in LAWS if law.mode == mode)


def law_id(mode: str, name: str) -> int:
    """Integer id of law ``name`` in ``mode``; ValueError naming the choices otherwise."""
    if mode not in MODES:
        raise ValueError(f"unknown contact mode {mode!r}; choose one of {MODES}")
    names = [law.name for law in laws(mode)]
    if name not in names:
        raise ValueError(f"unknown {mode} law {name!r}; choose one of {names}")
    return names.index(name)


def get(mode: str, name: str) -> Law:
    """The registry row of one law."""
    return laws(mode)[law_id(mode, name)]


def history_layout(names: dict) -> tuple[dict, int]:
    """Offsets of each mode's history values in a contact's history row, and the row
    length, for the laws ``names = {mode: law name}``."""
    offsets, size = {}, 0
    for mode in HISTORY_ORDER:
        offsets[mode] = size
        size += get(mode, names[mode]).history
    return offsets, size


# integer ids used by the compiled dispatcher, generated from the table above
NORMAL = {law.name: k for k, law in enumerate(laws("normal"))}
DAMPING = {law.name: k for k, law in enumerate(laws("damping"))}
TANGENTIAL = {law.name: k for k, law in enumerate(laws("tangential"))}
ROLLING = {law.name: k for k, law in enumerate(laws("rolling"))}
TWISTING = {law.name: k for k, law in enumerate(laws("twisting"))}
# model array: the five law ids (MODES order), the limit_damping flag, the five history
# offsets (MODES order) at HISTORY + mode index, then the planar flag (1 for disks in
# the x-y plane: the springs take their 2D form, physics/contact.py)
LIMIT_DAMPING = len(MODES)
HISTORY = len(MODES) + 1
PLANAR = HISTORY + len(MODES)
