"""Analyses of the linear structure: natural frequencies (more to come: Campbell, stationary)."""

from .modes import Modes, natural_frequencies

__all__ = ["Modes", "natural_frequencies"]
