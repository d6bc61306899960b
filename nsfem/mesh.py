"""Line meshes of a beam stack: generated from an element count or read with meshio.

A :class:`StackMesh` holds, per segment, the sorted node coordinates x. Every mesh has
nodes at segment ends, junctions, contact points and hat-weight extents, so contact
kinematics evaluate at nodes. Files hold one line cell set per segment, named like
the segment (meshio ``cell_sets``, or Gmsh physical names); points sit at
(x, y_c, z_c) so the file shows the stack as it is.

>>> from nsfem.scene import load_scene
>>> stack = load_scene(None).stack
>>> m = generate(stack, 40)
>>> m.elements, len(m.nodes["delamination_0_upper"])
(40, 33)
"""

from __future__ import annotations

import contextlib
import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import SceneError
from .stack import BeamStack


@dataclass(frozen=True)
class StackMesh:
    """Node coordinates x (sorted, ascending) of every segment, by segment name."""

    nodes: dict[str, np.ndarray]

    @property
    def elements(self) -> int:
        """Elements along the length (sub-beams of one delamination counted once)."""
        spans = {}
        for x in self.nodes.values():
            spans[(x[0], x[-1])] = len(x) - 1
        return sum(spans.values())


def breakpoints(stack: BeamStack) -> np.ndarray:
    """Sorted x of every node a mesh must have (segment ends, contact points, hat extents)."""
    xs = set()
    for s in stack.segments:
        xs.update(stack.required_nodes(s.name))
    return np.array(sorted(xs))


def generate(stack: BeamStack, elements: int) -> StackMesh:
    """Distribute ``elements`` over the intervals between required nodes, in proportion to length.

    Each interval gets at least one element (largest-remainder rounding), so the total is
    exactly ``elements`` whenever that is at least the number of intervals.
    """
    bp = breakpoints(stack)
    lengths = np.diff(bp)
    if elements < len(lengths):
        raise SceneError("mesh.elements", f"{elements} is fewer than the {len(lengths)} intervals between "
                         "segment ends and contact points; use at least that many")
    share = lengths / lengths.sum() * elements
    counts = np.maximum(1, np.floor(share).astype(int))
    while counts.sum() < elements:  # hand out the rest by largest shortfall
        counts[np.argmax(share - counts)] += 1
    while counts.sum() > elements:  # intervals forced up to one element push others down
        over = np.where(counts > 1, counts - share, -np.inf)
        counts[np.argmax(over)] -= 1
    # linspace returns its end points exactly, so required nodes keep their coordinates
    pts = [bp[:1]] + [np.linspace(a, b, n + 1)[1:] for a, b, n in zip(bp[:-1], bp[1:], counts)]
    xs = np.concatenate(pts)
    nodes = {}
    for s in stack.segments:
        nodes[s.name] = xs[(xs >= s.start) & (xs <= s.end)].copy()
    return StackMesh(nodes)


def _cell_sets(mesh) -> dict[str, np.ndarray]:
    """Named sets of line cells (as arrays of point-index pairs) from a meshio mesh."""
    lines = [(i, cb.data) for i, cb in enumerate(mesh.cells) if cb.type == "line"]
    sets: dict[str, np.ndarray] = {}
    for name, per_block in (mesh.cell_sets or {}).items():
        parts = [mesh.cells[i].data[np.asarray(per_block[i], dtype=int)]
                 for i, _ in lines if i < len(per_block) and per_block[i] is not None and len(per_block[i])]
        if parts:
            sets[name] = np.concatenate(parts)
    phys = mesh.cell_data.get("gmsh:physical")
    if phys is not None:
        for name, (tag, dim) in ((k, v[:2]) for k, v in (mesh.field_data or {}).items()):
            if int(dim) != 1 or name in sets:
                continue
            parts = [data[np.asarray(phys[i]) == tag] for i, data in lines]
            parts = [p for p in parts if len(p)]
            if parts:
                sets[name] = np.concatenate(parts)
    return sets


def read(path: str | Path, stack: BeamStack, key: str = "mesh.file") -> StackMesh:
    """Read a meshio line mesh with one named cell set per segment; check the required nodes."""
    import meshio

    path = Path(path)
    if not path.is_file():
        raise SceneError(key, f"file not found: {path}")
    fmt = "gmsh" if path.suffix.lower() == ".msh" else None  # meshio would try ansys first
    try:
        # meshio prints to stdout and calls sys.exit when no reader fits: keep both contained
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            mesh = meshio.read(path, file_format=fmt)
    except (Exception, SystemExit) as exc:  # meshio raises many types for unreadable files
        why = str(exc) if str(exc) and not isinstance(exc, SystemExit) else "not a mesh meshio can read"
        raise SceneError(key, f"cannot read {path.name}: {why}") from None
    if not any(cb.type == "line" for cb in mesh.cells):
        raise SceneError(key, f"{path.name} has no line cells")
    sets = _cell_sets(mesh)
    nodes = {}
    for s in stack.segments:
        if s.name not in sets:
            raise SceneError(key, f"{path.name} has no cell set named {s.name!r} "
                             f"(sets found: {', '.join(sorted(sets)) or 'none'})")
        x = np.unique(mesh.points[np.unique(sets[s.name]), 0])
        tol = 1e-9 * max(1.0, abs(s.end), abs(s.start))
        for r in stack.required_nodes(s.name):
            j = np.argmin(np.abs(x - r))
            if abs(x[j] - r) > tol:
                raise SceneError(key, f"cell set {s.name!r} has no node at x={r} (segment end, junction or "
                                 "contact point)")
            x[j] = r
        if x[0] < s.start - tol or x[-1] > s.end + tol:
            raise SceneError(key, f"cell set {s.name!r} spans [{x[0]}, {x[-1]}], beyond the segment "
                             f"[{s.start}, {s.end}]")
        if np.any(np.diff(x) <= tol):
            raise SceneError(key, f"cell set {s.name!r} has coincident nodes")
        nodes[s.name] = x
    return StackMesh(nodes)


def write(path: str | Path, stack: BeamStack, mesh: StackMesh) -> Path:
    """Write the mesh as a Gmsh 2.2 ASCII file, one physical line group per segment."""
    import meshio

    points, cells, phys, field_data = [], [], [], {}
    for tag, s in enumerate(stack.segments, start=1):
        x = mesh.nodes[s.name]
        base = len(points)
        points += [(xi, s.offset[0], s.offset[1]) for xi in x]
        cells += [(base + k, base + k + 1) for k in range(len(x) - 1)]
        phys += [tag] * (len(x) - 1)
        field_data[s.name] = np.array([tag, 1])
    m = meshio.Mesh(np.array(points, float), [("line", np.array(cells))],
                    cell_data={"gmsh:physical": [np.array(phys)], "gmsh:geometrical": [np.array(phys)]},
                    field_data=field_data)
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    meshio.write(tmp, m, file_format="gmsh22", binary=False)
    tmp.replace(path)
    return path
