"""The deposition protocol: insert the grains in the container (random or loose
lattice), settle them under gravity until the equilibrium criterion holds, report the
sample (protocols.prepare.settle_report) and draw it."""
from typing import Literal

import numpy as np

from ..figures import save
from .base import Protocol, register
from .phases import SettleSettings, preparation


class DepositionSettings(SettleSettings):
    """Insert grains in the container and settle them under gravity."""

    kind: Literal["deposition"] = "deposition"


@register
class Deposition(Protocol):
    """Gravity deposition in the config's container."""

    kind = "deposition"
    settings = DepositionSettings
    summary = "insert the grains, settle them under gravity, report the packing"

    def __init__(self, settings, vessel):
        super().__init__(settings, vessel)
        self.phases = preparation(settings, vessel)

    @classmethod
    def cross_check(cls, config):
        settings = config.protocol
        settings.check_dim(config.run.dim)

    def results(self, engine, states):
        """The settled sample's report."""
        return states["settle"]["report"]

    def figures(self, rundir, series, results):
        """Kinetic energy, apparent weight, coordination and packing fraction against
        time (Karrech et al.'s Fig. 3; settling_figure)."""
        fig = settling_figure(series, results, f"{self.title}: packing fraction "
                              f"{results.get('packing_fraction', float('nan')):.3f}",
                              self.vessel.bottom_wall)
        return [save_figure(fig, rundir, "deposition.png")]


def settling_figure(series, report, title, bottom_wall):
    """The figure of a settled sample's ``report`` (phases.Settle) against time up to
    its end: kinetic energy, bottom force over the weight and coordination number from
    ``series`` (``bottom_wall`` names the floor's column), and the packing fraction of
    the report's history."""
    from ..figures import subplots

    t = series["time [s]"]
    settling = t <= report.get("time_s", np.inf) * (1 + 1e-12)
    fig, ax = subplots(1, 4, figsize=(18, 4))
    ax[0].semilogy(t[settling], (series["kinetic [J]"] + series["rotational [J]"])[settling])
    ax[0].set(xlabel="t [s]", ylabel="kinetic energy [J]")
    ax[1].plot(t[settling], series[f"force_{bottom_wall} [N]"][settling]
               / report["total_weight_N"])
    ax[1].axhline(1.0, color="k", lw=0.5)
    ax[1].set(xlabel="t [s]", ylabel="bottom force / weight [-]", ylim=(0.0, 2.0))
    ax[2].plot(t[settling], series["coordination [-]"][settling])
    ax[2].set(xlabel="t [s]", ylabel="coordination number [-]")
    rows = report.get("history", [])
    ax[3].plot([r["time_s"] for r in rows], [r["packing_fraction"] for r in rows])
    ax[3].set(xlabel="t [s]", ylabel="packing fraction [-]")
    fig.suptitle(title)
    fig.tight_layout()
    return fig


def save_figure(fig, rundir, name):
    """Write ``fig`` as figures/``name`` of the run directory; the path."""
    return save(fig, rundir.figures / name)
