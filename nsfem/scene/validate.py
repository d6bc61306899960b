"""A raw scene tree checked against :data:`~nsfem.scene.schema.SCHEMA`: unknown keys, types,
ranges, NaN/inf; defaults filled in."""

from __future__ import annotations

import copy
import math
from typing import Any

from ..errors import SceneError
from .schema import AXES, SCHEMA, Key


def defaults() -> dict:
    """The scene with every key at its default (high-level form, no delamination, no obstacle)."""
    out: dict = {}
    for name, spec in SCHEMA.items():
        if isinstance(spec, Key):
            out[name] = copy.deepcopy(spec.default)
        elif isinstance(spec, dict):
            out[name] = {k: [] if isinstance(v, list) else copy.deepcopy(v.default) for k, v in spec.items()}
    return out


def _check_value(key: str, spec: Key, value: Any) -> Any:
    """Type-check one value (with conversion int -> float) and run its range check."""

    def number(v, k):
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise SceneError(k, f"must be a number, got {v!r}")
        if not math.isfinite(v):
            raise SceneError(k, f"must be finite, got {v}")
        return float(v)

    kind = spec.kind
    if kind == "float?" and value is None:
        return None
    if kind in ("float", "float?"):
        value = number(value, key)
    elif kind == "int":
        if isinstance(value, float) and not math.isfinite(value):
            raise SceneError(key, f"must be finite, got {value}")
        if isinstance(value, bool) or not isinstance(value, int):
            raise SceneError(key, f"must be an integer, got {value!r}")
    elif kind == "str":
        if not isinstance(value, str):
            raise SceneError(key, f"must be a string, got {value!r}")
        if spec.choices and value not in spec.choices:
            raise SceneError(key, f"unknown value {value!r} (use {' | '.join(spec.choices)})")
    elif kind == "coef":   # a bearing coefficient: a number, or a list of one per speed of its table
        value = ([number(v, f"{key}.{i}") for i, v in enumerate(value)] if isinstance(value, list)
                 else number(value, key))
    elif kind == "bool":
        if not isinstance(value, bool):
            raise SceneError(key, f"must be true or false, got {value!r}")
    elif kind == "floats":
        if not isinstance(value, list):
            raise SceneError(key, f"must be a list of numbers, got {value!r}")
        value = [number(v, f"{key}.{i}") for i, v in enumerate(value)]
        if spec.length is not None and len(value) != spec.length:
            raise SceneError(key, f"must have {spec.length} entries, got {len(value)}")
    elif kind == "strs":
        if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
            raise SceneError(key, f"must be a list of strings, got {value!r}")
        for v in value:
            if spec.choices and v not in spec.choices:
                raise SceneError(key, f"unknown entry {v!r} (use {', '.join(spec.choices)})")
    elif kind == "points":
        if isinstance(value, int) and not isinstance(value, bool):
            if value < 1:
                raise SceneError(key, f"must be >= 1, got {value}")
        elif isinstance(value, list):
            value = [number(v, f"{key}.{i}") for i, v in enumerate(value)]
            if not value:
                raise SceneError(key, "the list of contact points is empty")
        else:
            raise SceneError(key, f"must be a count or a list of x positions, got {value!r}")
    if spec.check is not None and value is not None:
        msg = spec.check(value)
        if msg:
            raise SceneError(key, msg)
    return value


def _check_table(prefix: str, spec: dict, raw: Any) -> dict:
    if not isinstance(raw, dict):
        raise SceneError(prefix, f"must be a table, got {raw!r}")
    for k in raw:
        if k not in spec:
            if prefix.startswith("bearing.") and _axis_key(k):
                raise SceneError(f"{prefix}.{k}", f"unknown key: {AXES}; a bearing takes kyy, kzz, kyz, kzy, the same "
                                 "for c, and kxx (axial; no axial damping)")
            raise SceneError(f"{prefix}.{k}", f"unknown key (known: {', '.join(spec)})")
    return {k: _check_array(f"{prefix}.{k}", s[0], raw.get(k, [])) if isinstance(s, list) else
            _check_value(f"{prefix}.{k}", s, raw[k]) if k in raw else copy.deepcopy(s.default)
            for k, s in spec.items()}


def _check_array(prefix: str, spec: dict, items: Any) -> list[dict]:
    """An array of tables (``[[name]]``, or ``[[shaft.step]]`` inside a table), each checked against ``spec``."""
    if isinstance(items, dict):
        items = [items]
    if not isinstance(items, list):
        raise SceneError(prefix, f"must be an array of tables ([[{prefix}]]), got {items!r}")
    return [_check_table(f"{prefix}.{i}", spec, item) for i, item in enumerate(items)]


def _axis_key(k: str) -> bool:
    """A stiffness or damping key in another program's axes (ROSS's kxy, cxx): k or c and two of x, y, z."""
    return len(k) == 3 and k[0] in "kc" and all(a in "xyz" for a in k[1:])


def section_of(table: dict) -> str:
    """The section a raw ``[shaft]`` or ``[[segment]]`` table means: its ``section``, else a circle when it gives
    diameter or inner_diameter and neither width nor height (a diameter says circle), else a rectangle."""
    if "section" in table:
        return table["section"]
    round_ = any(k in table for k in ("diameter", "inner_diameter"))
    return "circle" if round_ and not any(k in table for k in ("width", "height")) else "rectangle"


def implied_defaults(raw: dict, tree: dict) -> dict:
    """``tree`` with the defaults that follow from other keys of ``raw``: a section left out is the one its
    keys imply (:func:`section_of`), and a rotor scene (one with ``[[bearing]]``) without ``shaft.supports``
    has no supports (free-free: its bearings hold it), never supports hidden under its bearings."""
    tables = [("shaft", raw.get("shaft"), tree["shaft"])]
    if isinstance(raw.get("segment"), list):
        tables += [(f"segment.{i}", t, s) for i, (t, s) in enumerate(zip(raw["segment"], tree["segment"]))]
    for _, t, out in tables:
        if isinstance(t, dict) and "section" not in t:
            out["section"] = section_of(t)
    shaft = raw.get("shaft") if isinstance(raw.get("shaft"), dict) else {}
    if tree["bearing"] and "supports" not in shaft:
        tree["shaft"]["supports"] = "free-free"
    return tree


def validate_tree(raw: dict) -> dict:
    """Check a raw scene tree against :data:`SCHEMA` and fill in defaults (no cross checks)."""
    if not isinstance(raw, dict):
        raise SceneError("", "a scene must be a TOML table")
    for k in raw:
        if k not in SCHEMA:
            raise SceneError(k, f"unknown key (known tables: {', '.join(SCHEMA)})")
    out: dict = {}
    for name, spec in SCHEMA.items():
        if isinstance(spec, Key):
            out[name] = _check_value(name, spec, raw[name]) if name in raw else copy.deepcopy(spec.default)
        elif isinstance(spec, dict):
            out[name] = _check_table(name, spec, raw.get(name, {}))
        else:
            out[name] = _check_array(name, spec[0], raw.get(name, []))
    return out
