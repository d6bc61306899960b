"""Shared helpers: uniform beams, frequencies sorted by dominant field."""

from __future__ import annotations

import numpy as np
import pytest

from nsfem.fem import build_model
from nsfem.scene import scene_from_tree

E, RHO, L = 2.1e11, 7800.0, 1.0


def beam_tree(supports="pinned-pinned", width=0.03, height=0.01, elements=40, axial="P1", theory="euler-bernoulli",
              **extra) -> dict:
    """A scene tree of a uniform (or delaminated, via ``extra``) shaft."""
    tree = {"shaft": {"length": L, "width": width, "height": height, "E": E, "rho": RHO, "supports": supports},
            "mesh": {"elements": elements, "axial": axial}, "beam": {"theory": theory},
            "reduction": {"method": "none"}}
    tree.update(extra)
    return tree


def beam_model(*args, **kwargs):
    return build_model(scene_from_tree(beam_tree(*args, **kwargs)))


def frequencies_by_field(model, modes) -> dict[str, np.ndarray]:
    fields = modes.fields
    f = np.asarray(modes.frequencies_hz)
    return {k: f[[i for i, x in enumerate(fields) if x == k]] for k in "UVW"}


@pytest.fixture
def classify():
    return frequencies_by_field
