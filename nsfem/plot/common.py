"""Shared plotting helpers: an off-screen figure and an atomic save.

Figures are made on matplotlib's Agg canvas directly (no pyplot: no backend to select, no global
figure list to close) at the resolution they are saved with, so that the text extents measured by
``fig.tight_layout()`` are those the saved picture is drawn with and are measured once (a figure drawn
at another resolution than it was laid out in measures every label again: 10-20 % of a plot's time).
"""

from __future__ import annotations

from pathlib import Path

from ..atomic import write_atomic

#: dots per inch of the PNGs (a 6.4 x 4.8 in figure: 832 x 624 pixels)
DPI = 130
#: the keywords of ``figure`` that lay out the axes (``Figure.subplots``); the others make the figure
SUBPLOT_KEYS = ("nrows", "ncols", "sharex", "sharey", "squeeze", "width_ratios", "height_ratios", "subplot_kw",
                "gridspec_kw")


def figure(**kw):
    """(figure, axes) like ``pyplot.subplots(**kw)``, on the Agg canvas (no display needed) at :data:`DPI`."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    grid = {k: kw.pop(k) for k in SUBPLOT_KEYS if k in kw}
    fig = Figure(**{"dpi": DPI, **kw})
    FigureCanvasAgg(fig)
    return fig, fig.subplots(**grid)


def save(fig, path: str | Path, dpi: int = DPI) -> Path:
    """Save ``fig`` as PNG through a temporary file and a rename."""
    return write_atomic(path, lambda tmp: fig.savefig(tmp, dpi=dpi, format="png"))
