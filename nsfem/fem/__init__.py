"""Finite elements of the beam stack (scikit-fem): forms, assembly, constraint elimination."""

from .assemble import FEModel, assemble, build_model
from .constraints import constraint_basis, project

__all__ = ["FEModel", "assemble", "build_model", "constraint_basis", "project"]
