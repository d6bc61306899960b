"""Periodic orbits of the non-smooth rotor: shooting on the exact flow, Floquet multipliers with saltation
matrices, continuation over a parameter (issue 36; design.md section 9, ``nsfem periodic``)."""

from .branch import OrbitBranch, orbit_branch
from .continuation import Branch, BranchPoint, continue_branch, critical_vector
from .flow import Flow, FlowMap, flow
from .shooting import PeriodicOrbit, classify, periodic_orbit

__all__ = ["Branch", "BranchPoint", "Flow", "FlowMap", "OrbitBranch", "PeriodicOrbit", "classify", "continue_branch",
           "critical_vector", "flow", "orbit_branch", "periodic_orbit"]
