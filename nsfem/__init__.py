"""nsfem: non-smooth dynamics of rotating beam stacks with frictional unilateral contacts.

Three lines from a scene to its natural frequencies::

    >>> import nsfem
    >>> model = nsfem.build_model(nsfem.load_scene(None, ["mesh.elements=20"]))
    >>> nsfem.natural_frequencies(model, "open", count=3).frequencies_hz.round(1).tolist()
    [43.4, 48.0, 83.3]

The names below are imported on first use (``import nsfem`` alone loads no SciPy: ``nsfem --help``
answers without it).
"""

from __future__ import annotations

import importlib
import importlib.util

from .errors import NsfemError, SceneError

__version__ = "0.1.0"
__all__ = ["FEModel", "Modes", "NsfemError", "Scene", "SceneError", "build_model", "load_scene",
           "natural_frequencies"]
#: the public names imported on first use, and their modules
_LAZY = {"Modes": ".analysis.modes", "natural_frequencies": ".analysis.modes", "FEModel": ".fem.assemble",
         "build_model": ".fem.assemble", "Scene": ".scene", "load_scene": ".scene"}


def __getattr__(name: str):
    """A public name of ``_LAZY``, or a subpackage (``nsfem.scene.load_scene`` after ``import nsfem``,
    as before the names were lazy), imported on first use."""
    if name in _LAZY:
        value = getattr(importlib.import_module(_LAZY[name], __name__), name)
    elif (name.isidentifier() and not name.startswith("_")   # a dotted name is no attribute (hasattr: False)
          and importlib.util.find_spec(f"{__name__}.{name}") is not None):
        value = importlib.import_module(f".{name}", __name__)
    else:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    globals()[name] = value  # looked up once
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))
