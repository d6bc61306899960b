"""Strict JSON: the one place nsfem turns its payloads into JSON text.

Every JSON the program writes (``--json`` on stdout, ``sweep.json``, ``fit.json``, run records, the
results file's ``meta``) goes through :func:`dumps`: numpy values become Python values, NaN and
infinities become ``null`` (RFC 8259 has no token for them; strict parsers reject ``NaN``), and
``allow_nan=False`` makes any that slipped through an error here, never a file others cannot read.

>>> dumps({"energy": float("nan"), "x": np.float64(2.5), "v": np.array([1.0, np.inf])})
'{"energy": null, "x": 2.5, "v": [1.0, null]}'
"""

from __future__ import annotations

import json
import math
from typing import Any, Callable

import numpy as np


def as_text(o: Any) -> str:
    """A ``default`` for :func:`dumps`: anything JSON has no type for, as its text (a path, say)."""
    return str(o)


def finite(o: Any, default: Callable[[Any], Any] | None = None) -> Any:
    """``o`` with numpy scalars and arrays as Python values and every non-finite float as None;
    ``default(o)`` for any other type JSON cannot hold (TypeError without one)."""
    if o is None or isinstance(o, (bool, int, str)):
        return o
    if isinstance(o, float):
        return o if math.isfinite(o) else None
    if isinstance(o, dict):
        return {k: finite(v, default) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [finite(v, default) for v in o]
    if isinstance(o, np.ndarray):
        return finite(o.tolist(), default)
    if isinstance(o, np.generic):
        return finite(o.item(), default)
    if default is None:
        raise TypeError(f"{type(o).__name__} is not JSON serializable")
    return finite(default(o), None)


def dumps(payload: Any, default: Callable[[Any], Any] | None = None, **kwargs) -> str:
    """Strict JSON text of ``payload`` (see the module's text); ``kwargs`` go to :func:`json.dumps`."""
    return json.dumps(finite(payload, default), allow_nan=False, **kwargs)
