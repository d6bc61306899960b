"""Shared plotting helpers: an off-screen figure and an atomic save."""

from __future__ import annotations

from pathlib import Path

from ..atomic import write_atomic


def figure(**kw):
    """A matplotlib figure on the Agg backend (no display needed)."""
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    return plt.subplots(**kw)


def save(fig, path: str | Path, dpi: int = 130) -> Path:
    """Save ``fig`` as PNG through a temporary file and a rename; close it."""
    import matplotlib.pyplot as plt

    try:
        return write_atomic(path, lambda tmp: fig.savefig(tmp, dpi=dpi, format="png"))
    finally:
        plt.close(fig)
