"""Time integration of the contact system (paper section 4): the system they share."""

from .problem import ContactSystem

__all__ = ["ContactSystem"]
