"""Contact kinematics: gap Jacobians of delamination interfaces and rigid stops."""

from .kinematics import normal_jacobian

__all__ = ["normal_jacobian"]
