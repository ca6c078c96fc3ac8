"""Materials, the contact model (one law per mode) and the pair-parameter table.

Mixing rules for materials i, j (walls have materials too and mix the same way):
  1/E* = (1-nu_i^2)/E_i + (1-nu_j^2)/E_j            (Hertz; Oquendo's V_iV_j/(V_i+V_j))
  1/G* = (2-nu_i)/G_i + (2-nu_j)/G_j, G = E/(2(1+nu))  (Mindlin; Karrech Eq. 6)
  kn, kt, gamma_n, friction, restitution and every other per-material parameter
  (slip_threshold, gamma_nt, alpha_n, alpha_t, rolling and twisting springs and
  dashpots): geometric mean sqrt(x_i x_j), so a material in contact with itself
  keeps its own value (LAMMPS mixes this way).
For identical materials the Hertz-Mindlin moduli are Karrech's E* = E/(2(1-nu^2)) and
G* = G/(2(2-nu)) (Karrech Eq. 5-6).
Restitution, when given, sets the damping of the chosen damping law: the exact
repulsive-only ratio for the linear law (Schwager & Poeschel 2007), alpha(e) for
Tsuji.  Any pair can be overridden column by column.
"""
from dataclasses import dataclass, field

import numpy as np

from ..physics import registry
from ..physics.registry import COL, NCOL

# per-material parameters mixed by the geometric mean (names of Material fields and
# of pair-table columns alike)
_MIXED = ("kn", "kt", "gamma_n", "damping_constant", "friction_sliding", "friction_static",
          "friction_rolling", "tangential_damping", "slip_threshold", "gamma_nt", "alpha_n",
          "alpha_t", "rolling_stiffness", "rolling_damping", "friction_twisting",
          "twisting_stiffness", "twisting_damping")


@dataclass(frozen=True)
class Material:
    """A grain or wall material (SI units).

    density [kg/m^3] (areal [kg/m^2] for 2D disks); youngs_modulus [Pa]; poisson_ratio [-];
    restitution [-] in (0, 1] or None; damping_constant [kg/s] (linear law);
    gamma_n [1/(s m^0.5)] (viscoelastic law); kn, kt [N/m] (linear springs);
    friction_sliding (mu_d, Oquendo's mu_k), friction_static (mu_s) [-];
    friction_rolling [-]: rolling friction mu_r of the 'constant' and 'epsd' rolling
    laws, and tan(theta_r) of the 'oquendo' tangential law (Oquendo Eq. 8-9);
    tangential_damping [-]: tangential/normal dashpot ratio;
    slip_threshold [m/s]: Oquendo's small contact-point speed below which grains
    stick or roll (Eq. 4, 7), default 1e-5 m/s;
    gamma_nt [1/s]: Oquendo's twisting damping (Eq. 2);
    alpha_n, alpha_t [-]: Karrech's dissipation coefficients (Eq. 7; 0.44 there);
    rolling_stiffness [N/m], rolling_damping [kg/s]: EPSD rolling spring and dashpot,
    acting as torques through R*^2;
    friction_twisting [-]: twisting limit torque mu_tw a |f_n| (a contact radius);
    twisting_stiffness [N m/rad], twisting_damping [N m s]: EPSD twisting.
    """

    name: str = "default"
    density: float = 2650.0
    youngs_modulus: float = 1e8
    poisson_ratio: float = 0.3
    restitution: float | None = None
    damping_constant: float = 0.0
    gamma_n: float = 0.0
    kn: float = 0.0
    kt: float = 0.0
    friction_sliding: float = 0.5
    friction_static: float = 0.5
    friction_rolling: float = 0.0
    tangential_damping: float = 0.0
    slip_threshold: float = 1e-5
    gamma_nt: float = 0.0
    alpha_n: float = 0.0
    alpha_t: float = 0.0
    rolling_stiffness: float = 0.0
    rolling_damping: float = 0.0
    friction_twisting: float = 0.0
    twisting_stiffness: float = 0.0
    twisting_damping: float = 0.0

    def __post_init__(self):
        checks = [("density", self.density > 0), ("youngs_modulus", self.youngs_modulus > 0),
                  ("poisson_ratio", -1.0 < self.poisson_ratio < 0.5),
                  ("restitution", self.restitution is None or 0.0 < self.restitution <= 1.0)]
        checks += [(k, getattr(self, k) >= 0) for k in _MIXED]
        for name, ok in checks:
            if not ok:
                raise ValueError(f"material {self.name!r}: {name} = {getattr(self, name)} "
                                 "is out of range")

    @property
    def shear_modulus(self) -> float:
        """G = E/(2(1+nu)) [Pa]."""
        return self.youngs_modulus / (2.0 * (1.0 + self.poisson_ratio))


@dataclass
class ContactModel:
    """One law per mode, by registry name, plus per-pair column overrides.

    limit_damping: keep the normal force repulsive, f_n = max(0, f_el + c dxi/dt)
    (Perez Eq. 14, 17); False lets it pull at the end of a contact, as LAMMPS does.
    overrides: {(material_i, material_j): {column: value}}, applied symmetrically.
    """

    normal: str = "hertz"
    damping: str = "none"
    tangential: str = "none"
    rolling: str = "none"
    twisting: str = "none"
    limit_damping: bool = True
    overrides: dict = field(default_factory=dict)

    def _names(self) -> dict:
        return dict(zip(registry.MODES, (self.normal, self.damping, self.tangential,
                                         self.rolling, self.twisting)))

    def ids(self, dim: int = 3) -> np.ndarray:
        """(12,) int64: law ids in registry mode order, the limit_damping flag, each
        mode's offset in the contact history row (registry.history_layout), then the
        planar flag (registry.PLANAR: 1 for ``dim`` 2, where the springs take their 2D
        form)."""
        names = self._names()
        ids = [registry.law_id(m, names[m]) for m in registry.MODES]
        offsets, _ = registry.history_layout(names)
        return np.array(ids + [int(self.limit_damping)] + [offsets[m] for m in registry.MODES]
                        + [int(dim == 2)], dtype=np.int64)

    @property
    def history_size(self) -> int:
        """Number of history values kept per contact."""
        return registry.history_layout(self._names())[1]

    def check(self, materials):
        """Reject combinations that cannot work (LAMMPS init() checks)."""
        self.ids()
        for m in materials:
            if self.normal == "hooke" and m.kn <= 0:
                raise ValueError(f"normal law 'hooke' needs kn > 0 in material {m.name!r}")
            if self.tangential == "cundall_strack" and m.kt <= 0:
                raise ValueError(f"tangential law 'cundall_strack' needs kt > 0 in material "
                                 f"{m.name!r}")
            if self.damping == "linear" and m.restitution is None and m.damping_constant == 0:
                raise ValueError(f"damping 'linear' needs restitution or damping_constant in "
                                 f"material {m.name!r}")
            if self.damping == "tsuji" and m.restitution is None:
                raise ValueError(f"damping 'tsuji' needs restitution in material {m.name!r}")
            if self.normal.startswith("walton_braun") and (m.kn <= 0 or m.restitution is None):
                raise ValueError(f"normal law {self.normal!r} needs kn > 0 and restitution in "
                                 f"material {m.name!r}")
            for mode, law, column in (("rolling", "epsd", "rolling_stiffness"),
                                      ("twisting", "epsd", "twisting_stiffness")):
                if getattr(self, mode) == law and getattr(m, column) <= 0:
                    raise ValueError(f"{mode} law {law!r} needs {column} > 0 in material "
                                     f"{m.name!r}")
            if self.damping == "viscoelastic" and m.gamma_n <= 0:
                raise ValueError(f"damping 'viscoelastic' needs gamma_n > 0 in material "
                                 f"{m.name!r}")
        if self.normal.startswith("walton_braun") and self.damping != "none":
            raise ValueError(f"normal law {self.normal!r} dissipates through its unloading "
                             "spring: use damping 'none'")
        if self.tangential.startswith("oquendo") and self.rolling != "none":
            raise ValueError(f"tangential law {self.tangential!r} has its own rolling friction "
                             "(friction_rolling = tan theta_r): use rolling 'none'")
        if self.damping == "linear" and self.normal != "hooke":
            raise ValueError("damping 'linear' goes with normal 'hooke' (its restitution is "
                             "exact only for the linear spring)")

    def pair_table(self, materials, dim: int = 3) -> np.ndarray:
        """params[i, j, column] for every pair of materials, mixed and overridden;
        ``dim`` sets the grains' inertia ratio I/(m R^2) (2/5 spheres, 1/2 disks)."""
        from ..physics.reference import linear_damping_ratio, tsuji_alpha

        self.check(materials)
        k = len(materials)
        if dim not in (2, 3):
            raise ValueError(f"dim must be 2 or 3, not {dim!r}")
        table = np.zeros((k, k, NCOL))
        table[:, :, COL["inertia_ratio"]] = 0.4 if dim == 3 else 0.5
        for i, a in enumerate(materials):
            for j, b in enumerate(materials):
                row = table[i, j]
                row[COL["youngs_eff"]] = 1.0 / ((1 - a.poisson_ratio**2) / a.youngs_modulus
                                                + (1 - b.poisson_ratio**2) / b.youngs_modulus)
                row[COL["shear_eff"]] = 1.0 / ((2 - a.poisson_ratio) / a.shear_modulus
                                               + (2 - b.poisson_ratio) / b.shear_modulus)
                for name in _MIXED:
                    row[COL[name]] = np.sqrt(getattr(a, name) * getattr(b, name))
                if a.restitution is not None and b.restitution is not None:
                    e = np.sqrt(a.restitution * b.restitution)
                    row[COL["restitution"]] = e
                    if self.damping == "linear":
                        row[COL["damping_ratio"]] = linear_damping_ratio(e)
                    if self.damping == "tsuji":
                        row[COL["tsuji_alpha"]] = tsuji_alpha(e)
        for (i, j), values in self.overrides.items():
            for name, value in values.items():
                if name not in COL:
                    raise ValueError(f"override of unknown column {name!r}; columns are "
                                     f"{list(COL)}")
                c = registry.COLUMNS[COL[name]]
                if not c.lo <= value <= c.hi:
                    raise ValueError(f"override {name} = {value} [{c.unit}] outside "
                                     f"[{c.lo}, {c.hi}]")
                table[i, j, COL[name]] = table[j, i, COL[name]] = value
        return table
