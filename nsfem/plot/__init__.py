"""PNG plots (matplotlib, Agg backend), written atomically."""

from .campbell import campbell_plot

__all__ = ["campbell_plot"]
