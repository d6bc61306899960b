"""Export of results for visualisation (VTK XML: .vtu series indexed by a .pvd)."""

from .vtu import displacements, stack_geometry, write_series

__all__ = ["displacements", "stack_geometry", "write_series"]
