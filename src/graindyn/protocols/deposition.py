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
        """Kinetic energy and bottom force against time (from the saved series)."""
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        t = series["time [s]"]
        fig, ax = plt.subplots(1, 2, figsize=(10, 4))
        ax[0].semilogy(t, series["kinetic [J]"] + series["rotational [J]"])
        ax[0].set(xlabel="t [s]", ylabel="kinetic energy [J]")
        ax[1].plot(t, series[f"force_{self.vessel.bottom_wall} [N]"]
                   / results["total_weight_N"])
        ax[1].axhline(1.0, color="k", lw=0.5)
        ax[1].set(xlabel="t [s]", ylabel="bottom force / weight [-]")
        fig.suptitle(f"{self.title}: packing fraction "
                     f"{results.get('packing_fraction', float('nan')):.3f}")
        return [save_figure(fig, rundir, "deposition.png")]


def save_figure(fig, rundir, name):
    """Write ``fig`` as figures/``name`` of the run directory, close it; the path."""
    import matplotlib.pyplot as plt

    fig.tight_layout()
    path = rundir.figures / name
    path.parent.mkdir(exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path
