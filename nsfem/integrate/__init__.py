"""Time integration of the contact system (paper sections 4 and 5.2).

``integrate(system, t_end, method=...)`` maps method names to :class:`Integrator`
subclasses: ``exact`` and ``rk`` (event-driven), ``penalty`` (spring-dashpot contacts, stiff
solver) and ``moreau`` (Moreau-Jean time stepping); see :mod:`nsfem.integrate.base` for the
contract a method follows.
"""

from . import moreau, penalty  # noqa: F401  (register the methods)
from .base import Integrator, integrate
from .event_driven import Exact, RungeKutta
from .moreau import MoreauJean
from .penalty import Penalty
from .problem import ContactSystem

__all__ = ["ContactSystem", "Exact", "Integrator", "MoreauJean", "Penalty", "RungeKutta", "integrate"]
