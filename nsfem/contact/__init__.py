"""Contact kinematics (gaps, slips) and the contact set of a reduced model."""

from .kinematics import gap_jacobian, slip_jacobian
from .set import ContactSet

__all__ = ["ContactSet", "gap_jacobian", "slip_jacobian"]
