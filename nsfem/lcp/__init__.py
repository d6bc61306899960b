"""Linear complementarity problems: Lemke's method and the contact LCPs (28), (29), (30-32)."""

from .builders import ContactLCP, contact_lcp, impact_lcp, stationary_lcp, transition_lcp
from .pivoting import LCPError, LCPResult, certificate, lemke

__all__ = ["ContactLCP", "LCPError", "LCPResult", "certificate", "contact_lcp", "impact_lcp", "lemke",
           "stationary_lcp", "transition_lcp"]
