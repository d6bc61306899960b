"""Export of results for visualisation (VTK XML: .vtu series indexed by a .pvd)."""

from .vtu import disk_geometry, displacements, stack_geometry, stator_geometry, write_series

__all__ = ["disk_geometry", "displacements", "stack_geometry", "stator_geometry", "write_series"]
