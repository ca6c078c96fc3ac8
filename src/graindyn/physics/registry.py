"""The one table of contact laws.

Every law belongs to a mode (normal, damping, tangential, rolling, twisting), has an
integer id (its position in its mode's list: generated here, never written twice),
the pair-table columns it reads, and the number of history values it keeps per
contact.  The pair-parameter table ``params[material_i, material_j, column]`` has the
columns of ``COLUMNS``; kernels index it with the integer constants of ``COL``.

To add a law: write its scalar function in physics/<mode>.py, add a row below, add a
branch in physics/contact.py, and an analytic test.  (Numba caches a kernel against
its own source file: after changing COLUMNS, clear the cache with
``python -m graindyn.cache clear``.)
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
)
COL = {c.name: k for k, c in enumerate(COLUMNS)}
NCOL = len(COLUMNS)

LAWS = (
    Law("normal", "hooke", ("kn",), 0, "Perez Eq. 14: f = kn xi"),
    Law("normal", "hertz", ("youngs_eff",), 0, "Perez Eq. 17, Oquendo Eq. 1: f = 4/3 E* sqrt(R*) xi^1.5"),
    Law("damping", "none", (), 0, "no normal dissipation"),
    Law("damping", "linear", ("damping_ratio", "damping_constant"), 0,
        "Perez Eq. 14-16: f = Gamma xi', Gamma = 2 beta sqrt(kn m*) + Gamma_0"),
    Law("damping", "viscoelastic", ("gamma_n",), 0,
        "Oquendo Eq. 1, Perez Eq. 17: f = m* gamma_n sqrt(xi) xi'"),
    Law("damping", "tsuji", ("tsuji_alpha",), 0,
        "Tsuji et al. 1992 as in LAMMPS: f = alpha sqrt(m* f_el/xi) xi'"),
    Law("tangential", "none", (), 0, "frictionless"),
    Law("tangential", "coulomb", ("friction_sliding",), 0,
        "Perez Eq. 19: f = -mu_d f_n v_t/|v_t|"),
    Law("tangential", "cundall_strack", ("kt", "tangential_damping", "friction_sliding"), 3,
        "Perez Eq. 20-23: capped spring + dashpot, 3D vector form"),
    Law("tangential", "mindlin", ("shear_eff", "tangential_damping", "friction_sliding"), 3,
        "Mindlin no-slip spring kt = 8 G* sqrt(R* xi) with Coulomb cap (Karrech Eq. 6)"),
    Law("rolling", "none", (), 0, "no rolling resistance"),
    Law("twisting", "none", (), 0, "no twisting resistance"),
)


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


# integer ids used by the compiled dispatcher, generated from the table above
NORMAL = {law.name: k for k, law in enumerate(laws("normal"))}
DAMPING = {law.name: k for k, law in enumerate(laws("damping"))}
TANGENTIAL = {law.name: k for k, law in enumerate(laws("tangential"))}
