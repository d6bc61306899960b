"""Shared plotting helpers: an off-screen figure and an atomic save."""

from __future__ import annotations

import os
from pathlib import Path


def figure(**kw):
    """A matplotlib figure on the Agg backend (no display needed)."""
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    return plt.subplots(**kw)


def save(fig, path: str | Path, dpi: int = 130) -> Path:
    """Save ``fig`` as PNG through a temporary file and a rename; close it."""
    import matplotlib.pyplot as plt

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.stem}.{os.getpid()}.tmp.png")
    try:
        fig.savefig(tmp, dpi=dpi)
        os.replace(tmp, path)
    finally:
        plt.close(fig)
        if tmp.exists():
            tmp.unlink()
    return path
