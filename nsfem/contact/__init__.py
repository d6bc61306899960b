"""Contact kinematics: gap Jacobians of delamination interfaces and rigid stops."""

from .kinematics import gap_jacobian

__all__ = ["gap_jacobian"]
