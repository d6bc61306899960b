"""Scenes: the shipped scene is the paper's, overrides, and high- vs low-level forms."""

from __future__ import annotations

import numpy as np
import pytest

from nsfem import build_model, load_scene, natural_frequencies
from nsfem.scene import apply_override, defaults, parse_value, scene_from_tree


def test_shipped_scene_is_the_papers_shaft():
    s = load_scene(None)
    sh = s["shaft"]
    assert (sh["length"], sh["width"], sh["height"], sh["rho"]) == (1.0, 0.02, 0.02, 7500.0)
    assert (sh["E"], sh["supports"]) == (2.1e11, "pinned-pinned")  # the two stated assumptions
    d = s["delamination"][0]
    assert (d["start"], d["end"], d["upper_height"], d["contact_points"]) == (0.1, 0.9, 0.011, 9)
    up, lo = s.stack.segment("delamination_0_upper"), s.stack.segment("delamination_0_lower")
    # 0.02 - 0.011 rounds once (0.009000000000000001)
    assert up.height == pytest.approx(0.011, rel=1e-15) and lo.height == pytest.approx(0.009, rel=1e-15)
    # the intact section's centroid stays on the axis: A_u z_u + A_l z_l = 0 (products ~1e-6 m^3:
    # 1e-20 is 45 eps of them; measured 0), faces meet (operands <= 5.5 mm, ulp 8.7e-19; measured 0)
    assert up.area * up.offset[1] + lo.area * lo.offset[1] == pytest.approx(0.0, abs=1e-20)
    assert up.offset[1] - up.height / 2 == pytest.approx(lo.offset[1] + lo.height / 2, abs=1e-17)
    xs = [c.x for c in s.stack.contacts]
    assert xs == pytest.approx(np.linspace(0.1, 0.9, 11)[1:-1], abs=1e-15)  # a few ulps of x <= 0.9


def test_override_parsing_and_list_items():
    assert parse_value("[0.0, 1e-5]") == [0.0, 1e-5]
    assert parse_value('"stationary"') == "stationary" and parse_value("stationary") == "stationary"
    assert parse_value("true") is True and parse_value("free-free") == "free-free"
    tree = {"delamination": [{"start": 0.1}]}
    apply_override(tree, "delamination.0.friction=0.3")
    apply_override(tree, "delamination.1.start=0.95")  # one past the end appends
    apply_override(tree, "rotation.speed_hz=18")
    assert tree == {"delamination": [{"start": 0.1, "friction": 0.3}, {"start": 0.95}],
                    "rotation": {"speed_hz": 18}}


def test_defaults_cover_every_table():
    d = defaults()
    assert d["mesh"]["elements"] == 40 and d["reduction"]["method"] == "craig-bampton"
    assert d["rotation"]["speed_hz"] == 0.0 and d["beam"]["theory"] == "euler-bernoulli"
    assert "delamination" not in d  # arrays of tables are empty unless written
    # a scene with nothing in it is an intact pinned-pinned shaft
    s = scene_from_tree({})
    assert [seg.name for seg in s.stack.segments] == ["intact_0"] and not s.stack.contacts


LOW_LEVEL_DEFAULT = {   # the shipped scene's shaft (its rho is the paper's 7500, not the default steel 7850)
    "segment": [
        {"name": "intact_0", "start": 0.0, "end": 0.1, "rho": 7500.0},
        {"name": "upper", "start": 0.1, "end": 0.9, "height": 0.011, "offset": [0.0, 0.0045], "rho": 7500.0},
        {"name": "lower", "start": 0.1, "end": 0.9, "height": 0.009, "offset": [0.0, -0.0055], "rho": 7500.0},
        {"name": "intact_1", "start": 0.9, "end": 1.0, "rho": 7500.0},
    ],
    "junction": [{"x": 0.1, "master": "intact_0", "slaves": ["upper", "lower"]},
                 {"x": 0.9, "master": "intact_1", "slaves": ["upper", "lower"]}],
    "support": [{"segment": "intact_0", "x": 0.0, "fix": ["U", "V", "W"]},
                {"segment": "intact_1", "x": 1.0, "fix": ["V", "W"]}],
    "contact": [{"kind": "interface", "x": x, "segments": ["upper", "lower"]}
                for x in (0.18, 0.26, 0.34, 0.42, 0.5, 0.58, 0.66, 0.74, 0.82)],
}


@pytest.mark.parametrize("contact", ["open", "closed"])
def test_low_level_form_gives_the_same_model(contact):
    high = build_model(load_scene(None))
    low = build_model(scene_from_tree(LOW_LEVEL_DEFAULT))
    assert low.n == high.n
    # same structure, segment names aside: identical matrices up to round-off of the offsets (the
    # high-level z_u is 0.0045000000000000005, the low-level one 0.0045; measured 1.2e-16)
    for name in ("M", "K"):
        a, b = getattr(high, name), getattr(low, name)
        assert abs(a - b).max() <= 1e-14 * abs(a).max()
    # eigensolver round-off: eps x the componentwise condition of the Rayleigh quotient (<= 1.4e6)
    # = 3e-10 (measured 9e-13 to 7.5e-12 over four kernels)
    fh = natural_frequencies(high, contact, 6).frequencies_hz
    fl = natural_frequencies(low, contact, 6).frequencies_hz
    assert np.allclose(fh, fl, rtol=1e-9)
