"""What every study writes: its table (CSV), its JSON and a note of the machine."""

from __future__ import annotations

import csv
import json
import os
import platform
from pathlib import Path

import numpy as np


def machine() -> dict:
    """The facts a timing needs next to it."""
    return {"cpu_count": os.cpu_count(), "python": platform.python_version(), "numpy": np.__version__,
            "processor": platform.processor() or platform.machine(),
            "openblas_threads": os.environ.get("OPENBLAS_NUM_THREADS")}


def write_outputs(out: Path, name: str, rows: list[dict], payload: dict) -> None:
    """``<out>/<name>.json`` (payload) and ``<out>/<name>.csv`` (rows; union of their keys)."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    (out / f"{name}.json").write_text(json.dumps(payload, indent=1))
    keys = list(dict.fromkeys(k for r in rows for k in r))
    with open(out / f"{name}.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=keys)
        w.writeheader()
        w.writerows(rows)


def save_figure(fig, path: Path, dpi: int = 110) -> None:
    """Write a matplotlib figure atomically (a temporary file beside it, then renamed) and close it."""
    import matplotlib.pyplot as plt

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp.png")
    fig.savefig(tmp, dpi=dpi)
    tmp.replace(path)
    plt.close(fig)
