"""Time integration of the contact system (paper section 4).

``integrate(system, t_end, method=...)`` maps method names to :class:`Integrator`
subclasses (``exact``, ``rk``); see :mod:`nsfem.integrate.base` for the contract.
"""

from .base import Integrator, integrate
from .event_driven import Exact, RungeKutta
from .problem import ContactSystem

__all__ = ["ContactSystem", "Exact", "Integrator", "RungeKutta", "integrate"]
