"""nsfem: non-smooth dynamics of rotating beam stacks with frictional unilateral contacts.

Three lines from a scene to its natural frequencies::

    >>> import nsfem
    >>> model = nsfem.build_model(nsfem.load_scene(None, ["mesh.elements=20"]))
    >>> nsfem.natural_frequencies(model, "open", count=3).frequencies_hz.round(1).tolist()
    [43.4, 48.0, 83.3]
"""

from .analysis.modes import Modes, natural_frequencies
from .errors import NsfemError, SceneError
from .fem.assemble import FEModel, build_model
from .scene import Scene, load_scene

__version__ = "0.1.0"
__all__ = ["FEModel", "Modes", "NsfemError", "Scene", "SceneError", "build_model", "load_scene",
           "natural_frequencies"]
