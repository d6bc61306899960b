"""``--set KEY=VALUE`` overrides of a raw scene tree (dotted keys, list items by index)."""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

from ..errors import NsfemError, SceneError
from .schema import MAX_NESTING, PATH_KEYS, SCHEMA


def parse_value(text: str) -> Any:
    """A ``--set`` value: a TOML value (number, "string", [list], true), else the bare string.

    >>> parse_value("[0.0, 1e-5]"), parse_value('"stationary"'), parse_value("stationary"), parse_value("18")
    ([0.0, 1e-05], 'stationary', 'stationary', 18)
    """
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text
    except RecursionError:  # a value nested deeper than the parser's recursion limit
        raise SceneError("", f"the value is nested too deeply to parse (a scene needs at most {MAX_NESTING} "
                         "levels of tables and lists)") from None


def range_ends(option: str, key: str, low: str, high: str) -> tuple[float, float]:
    """The two ends of a ``KEY=LOW:HIGH`` option as finite numbers (``option`` names it in the error: one line).

    >>> range_ends("--vary", "rotation.speed_hz", "10", " 2e1")
    (10.0, 20.0)
    """
    ends = []
    for name, text in (("LOW", low), ("HIGH", high)):
        try:
            v = float(text)
        except ValueError:
            v = float("nan")
        if not (v == v and abs(v) != float("inf")):
            raise NsfemError(f"{option} {key}: {name} must be a finite number, got {text.strip()!r}")
        ends.append(v)
    return ends[0], ends[1]


def nesting_depth(value: Any) -> int:
    """Levels of tables and lists in ``value`` (0 for a number or string), without recursion.

    >>> nesting_depth(1), nesting_depth([1, [2]]), nesting_depth({"a": [{"b": 1}]}), nesting_depth([[]])
    (0, 2, 3, 2)
    """
    depth, level = 0, [value]
    while level := [node for node in level if isinstance(node, (dict, list))]:
        depth += 1
        level = [v for node in level for v in (node.values() if isinstance(node, dict) else node)]
    return depth


def _check_nesting(value: Any, key: str, what: str) -> None:
    d = nesting_depth(value)
    if d > MAX_NESTING:
        raise SceneError(key, f"{what} is nested {d} levels deep; a scene needs at most {MAX_NESTING} levels of "
                         "tables and lists")


def apply_override(tree: dict, assignment: str, cwd: Path | None = None) -> None:
    """Apply one ``KEY=VALUE`` to a raw scene tree in place (dotted keys, list items by index)."""
    if "=" not in assignment:
        raise SceneError(assignment, "an override must look like KEY=VALUE")
    key, text = assignment.split("=", 1)
    key = key.strip()
    parts = key.split(".")
    if not key or any(p == "" for p in parts):
        raise SceneError(key or assignment, "empty key in override")
    try:
        value = parse_value(text.strip())
    except SceneError as exc:
        raise SceneError(key, exc.reason) from None
    _check_nesting(value, key, "the value")
    if key in PATH_KEYS and isinstance(value, str) and value:
        value = str((cwd or Path.cwd()) / value)
    node: Any = tree
    for i, part in enumerate(parts[:-1]):
        nxt_is_index = _is_index(parts[i + 1])
        node = _step(node, part, key, create=[] if nxt_is_index else {})
    last = parts[-1]
    if isinstance(node, list):
        idx = _index(node, last, key)
        if idx == len(node):
            node.append(value)
        else:
            node[idx] = value
    elif isinstance(node, dict):
        node[last] = value
    else:
        raise SceneError(key, f"{'.'.join(parts[:-1])} is not a table")


def _is_index(part: str) -> bool:
    return part.isascii() and part.isdigit()


def _index(node: list, part: str, key: str) -> int:
    if not _is_index(part):
        raise SceneError(key, f"{part!r} must be a list index")
    idx = int(part)
    if idx > len(node):
        raise SceneError(key, f"index {idx} is past the end of a list of {len(node)}")
    return idx


def _step(node: Any, part: str, key: str, create: Any) -> Any:
    if isinstance(node, list):
        idx = _index(node, part, key)
        if idx == len(node):
            node.append({})
        return node[idx]
    if isinstance(node, dict):
        if _is_index(part):
            raise SceneError(key, f"{part} indexes a table, not a list")
        if part not in node:
            # a known array of tables ([[delamination]]) is created as a list
            node[part] = [] if isinstance(SCHEMA.get(part), list) and node is not None else create
        return node[part]
    raise SceneError(key, f"cannot descend into {part!r}")


def missing_item(tree: Any, key: str) -> str | None:
    """The item (``crack.1``) that dotted ``key`` indexes one or more past the end of its list in
    ``tree`` (a validated scene), else None. An override there appends an item (``--set
    crack.1.depth=0.2`` adds a crack); a fit or sweep that varies such a key must refuse it, not add
    one in silence. An unknown key or a non-index is left to :func:`load_scene` to refuse.

    >>> missing_item({"crack": [{"x": 0.1}]}, "crack.1.depth"), missing_item({"crack": [{"x": 0.1}]}, "crack.0.x")
    ('crack.1', None)
    """
    node = tree
    parts = key.split(".")
    for i, part in enumerate(parts[:-1]):
        if isinstance(node, list):
            if not _is_index(part):
                return None
            if int(part) >= len(node):
                return ".".join(parts[:i + 1])
            node = node[int(part)]
        elif isinstance(node, dict) and part in node:
            node = node[part]
        else:
            return None
    return None
