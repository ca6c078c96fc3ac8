"""The deposition protocol: insert the grains in the container (random or loose
lattice), settle them under gravity until the equilibrium criterion holds, report the
sample (protocols.prepare.settle_report) and draw it."""
from typing import Literal

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
        """Kinetic energy (from the saved series), and the apparent weight, coordination
        and packing fraction of the settling history (Karrech et al.'s Fig. 3), against
        time."""
        fig = settling_figure(series, results, f"{self.title}: packing fraction "
                              f"{results.get('packing_fraction', float('nan')):.3f}")
        return [save_figure(fig, rundir, "deposition.png")]


def settling_figure(series, report, title):
    """The figure of a settled sample's ``report`` (phases.Settle): kinetic energy
    against time from ``series``, and its history (bottom force over the weight,
    coordination number, packing fraction) against time."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = series["time [s]"]
    fig, ax = plt.subplots(1, 4, figsize=(18, 4))
    ax[0].semilogy(t, series["kinetic [J]"] + series["rotational [J]"])
    ax[0].set(xlabel="t [s]", ylabel="kinetic energy [J]")
    rows = report.get("history", [])
    times = [r["time_s"] for r in rows]
    for a, key, label in ((ax[1], "apparent_weight_ratio", "bottom force / weight [-]"),
                          (ax[2], "coordination", "coordination number [-]"),
                          (ax[3], "packing_fraction", "packing fraction [-]")):
        a.plot(times, [r[key] for r in rows])
        a.set(xlabel="t [s]", ylabel=label)
    ax[1].axhline(1.0, color="k", lw=0.5)
    fig.suptitle(title)
    fig.tight_layout()
    return fig


def save_figure(fig, rundir, name):
    """Write ``fig`` as figures/``name`` of the run directory, close it; the path."""
    import matplotlib.pyplot as plt

    fig.tight_layout()
    path = rundir.figures / name
    path.parent.mkdir(exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path
