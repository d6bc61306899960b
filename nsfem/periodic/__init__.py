"""Periodic orbits of the non-smooth rotor: shooting on the exact flow, Floquet multipliers with saltation
matrices (issue 36; design.md section 9, ``nsfem periodic``)."""

from .flow import Flow, flow
from .shooting import PeriodicOrbit, classify, periodic_orbit

__all__ = ["Flow", "PeriodicOrbit", "classify", "flow", "periodic_orbit"]
