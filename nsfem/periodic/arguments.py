"""Arguments of the periodic-orbit functions checked at the boundary: one-line NsfemError naming the argument."""

from __future__ import annotations

import math
import numbers

import numpy as np

from ..errors import NsfemError


def real_number(name: str, value, *, positive: bool = False) -> float:
    """``value`` as a finite float (> 0 with ``positive``); NsfemError naming ``name`` otherwise."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (numbers.Real, np.floating, np.integer)) \
            or not math.isfinite(value) or (positive and value <= 0):
        raise NsfemError(f"periodic: {name} must be a finite number{' > 0' if positive else ''}, got {value!r}")
    return float(value)


def whole_number(name: str, value, minimum: int) -> int:
    """``value`` as an int >= ``minimum`` (an integral float accepted); NsfemError naming ``name`` otherwise."""
    ok = not isinstance(value, (bool, np.bool_)) and isinstance(value, (numbers.Real, np.floating, np.integer)) \
        and math.isfinite(value) and float(value).is_integer() and value >= minimum
    if not ok:
        raise NsfemError(f"periodic: {name} must be a whole number >= {minimum}, got {value!r}")
    return int(value)


def vector(x, n: int) -> np.ndarray:
    """A state vector given as numbers, as a float array (its length is checked where it is used)."""
    try:
        return np.array(x, dtype=float)
    except (TypeError, ValueError):
        raise NsfemError(f"periodic: the starting state must be two finite vectors of length {n}, got "
                         f"{type(x).__name__} {str(x)[:40]!r}") from None
