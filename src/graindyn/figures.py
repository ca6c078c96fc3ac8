"""Matplotlib figures made without pyplot.

pyplot keeps one global state (the current figure and its figure managers), which the
threads of a GPU sweep (engines/soft/gpu/batch.py runs each run of the sweep in a
thread of its own) would share; a Figure made directly belongs to its caller alone, is
freed with it, and saves to PNG through the Agg canvas without a backend switch."""


def subplots(nrows=1, ncols=1, *, figsize, **options):
    """A new Figure of ``figsize`` (width, height) [inch] and its axes, as
    pyplot.subplots gives them (``options``: sharex, sharey, squeeze...)."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=figsize)
    return fig, fig.subplots(nrows, ncols, **options)


def save(fig, path, dpi=120):
    """Lay ``fig`` out and write it to ``path`` (its folder made); returns the path."""
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=dpi)
    return path
