"""Off-screen picture of the deformed rotor at one output time (``nsfem render``).

pyvista draws the stack's solids (:func:`~nsfem.export.vtu.stack_geometry`) displaced by
``exaggeration`` times the beam kinematics, coloured by the vertical displacement u3, with the parts of
the scene around it (:func:`scene_meshes`): disks (translucent cylinders of
:func:`~nsfem.export.vtu.disk_size`, moving rigidly with their node), stator rings (the model's polygon,
:func:`~nsfem.export.vtu.stator_geometry`, each facet coloured by its gap), bearings (a spring from the
shaft down to a ground block at their x; a thrust bearing, kxx alone, along -x from the axis), lateral
supports (a cone under the shaft), cracks (a red collar
at their x, thick around the cracked part of the section) and the other contact points (spheres coloured
by their gap).
A ring's clearance is drawn ``exaggeration`` times as wide as it is, like the displacements, so that the
drawn shaft touches the drawn ring where the gap closes; the caption says so. An axes triad (x along the
shaft) and a ruler along x give the directions and the length scale. It renders without a display
through VTK's EGL window (Mesa); ``VTK_DEFAULT_OPENGL_WINDOW`` is set to ``vtkEGLRenderWindow`` unless the
user chose another (OSMesa builds of VTK work the same).
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np

from ..atomic import write_atomic
from ..errors import NsfemError
from .vtu import (contact_points, crack_displacements, crack_faces, crack_geometry, disk_displacements, disk_geometry,
                  displacements, stack_geometry, stator_geometry)

#: Colour bars: short, in the lower corners, narrow, beside the stack rather than over it
BAR = {"height": 0.4, "width": 0.04, "position_y": 0.06, "title_font_size": 16, "label_font_size": 14}
#: The largest drawn displacement, in stack lengths: beyond it the stack leaves the picture.
MAX_SHOWN = 10.0
#: colours of the parts drawn in one colour (the legend's)
COLOURS = {"disks": "silver", "bearings": "dimgray", "supports": "dimgray", "cracks": "red"}
#: the legend's words for them
LABELS = {"disks": "grey: disks (translucent)", "bearings": "dark grey: bearings (springs to ground; along x: thrust)",
          "supports": "dark grey cones: supports",
          "cracks": "red: crack (a collar at its x, thick on the cracked side)",
          "stators": "stator rings: facets coloured by their gap"}


#: pixels between the window's edge and the caption
MARGIN = 12


def ruler_labels(length: float) -> int:
    """The number of labels of a ruler over ``length`` [m] (from 0) so that they fall on round numbers: steps of
    1, 2, 2.5 or 5 x 10^k that divide it into 3 to 8 parts, the count nearest 5 parts (else 5 labels).

    >>> ruler_labels(1.5), ruler_labels(0.8), ruler_labels(0.6), ruler_labels(1.0), ruler_labels(0.77)
    (7, 5, 7, 6, 5)
    """
    if not (math.isfinite(length) and length > 0):
        return 5
    k = math.floor(math.log10(length))
    parts = [length / (m * 10.0 ** e) for e in (k - 1, k) for m in (1.0, 2.0, 2.5, 5.0)]
    whole = [round(n) for n in parts if 3 <= round(n) <= 8 and abs(n - round(n)) < 1e-9 * n]
    return min(whole, key=lambda n: abs(n - 5)) + 1 if whole else 5


def _depth(seg) -> float:
    """The section's extent along z (a circle's diameter is its ``width``)."""
    return seg.width if seg.section == "circle" else seg.height


def _lateral(model, q_full, x: float) -> tuple[object, float, float]:
    """(segment carrying x, V, W there): the rotor's lateral displacement at x."""
    name = model.stack.carrier(x) or next(s.name for s in model.stack.segments if s.start <= x <= s.end)
    return model.stack.segment(name), float(q_full[model.dof(name, "V", x)]), float(q_full[model.dof(name, "W", x)])


def _spring(x: float, y: float, top: float, size: float):
    """A zigzag spring of 6 coils from ``top`` down 3 ``size``, on a ground block ``size`` wide."""
    import pyvista as pv

    n = 12
    z = top - np.concatenate([[0.0], 0.5 * size + 2.0 * size * np.arange(n + 1) / n, [3.0 * size]])
    dy = np.concatenate([[0.0, 0.0], 0.35 * size * (-1.0) ** np.arange(n - 1), [0.0, 0.0]])
    line = pv.lines_from_points(np.column_stack([np.full(z.size, x), y + dy, z])).tube(radius=0.05 * size)
    block = pv.Box(bounds=(x - 0.6 * size, x + 0.6 * size, y - 0.6 * size, y + 0.6 * size,
                           z[-1] - 0.3 * size, z[-1]))
    return line.merge(block.triangulate())


def scene_meshes(model, q_full, gap, scale: float) -> dict[str, object]:
    """The meshes of the picture for the full dofs ``q_full`` and the gaps ``gap`` (one per contact) at one
    time, displacements (and ring clearances) drawn ``scale`` times: ``stack`` (point data ``u3 [mm]``) and,
    where the model has them, ``disks``, ``stators`` (cell data ``gap [mm]``), ``contacts`` (spheres of the
    contacts that are neither a stator's facet nor a crack's, point data ``gap [mm]``), ``bearings``,
    ``supports`` and ``cracks``."""
    import pyvista as pv

    q_full = np.asarray(q_full, dtype=float).ravel()
    gap = np.asarray(gap, dtype=float).ravel()
    points, cells, _, _ = stack_geometry(model)
    u = displacements(model, q_full)
    length = float(np.ptp(points[:, 0])) or 1.0
    size = max(_depth(s) for s in model.stack.segments)   # the glyphs' size: the shaft's depth
    grid = pv.UnstructuredGrid({pv.CellType.HEXAHEDRON: cells}, points + scale * u)
    grid.point_data["u3 [mm]"] = 1e3 * u[:, 2]
    out: dict[str, object] = {"stack": grid}
    dpts, dcells, _, _ = disk_geometry(model)
    if len(dcells):
        out["disks"] = pv.UnstructuredGrid({pv.CellType.HEXAHEDRON: dcells},
                                           dpts + scale * disk_displacements(model, q_full))
    spts, scells, _, facet = stator_geometry(model, clearance_scale=scale, width=1.5 * size)
    if len(scells):
        ring = pv.UnstructuredGrid({pv.CellType.HEXAHEDRON: scells}, spts)
        ring.cell_data["gap [mm]"] = 1e3 * gap[facet]
        out["stators"] = ring
    pos, du = contact_points(model, q_full)
    point = [k for k, c in enumerate(model.stack.contacts) if c.angle is None and c.kind != "crack"]
    if point:
        cloud = pv.PolyData(pos[point] + scale * du[point])
        cloud.point_data["gap [mm]"] = 1e3 * gap[point]
        out["contacts"] = cloud.glyph(geom=pv.Sphere(radius=0.012 * length), scale=False, orient=False)
    springs = []
    for b in model.stack.bearings:
        seg, V, W = _lateral(model, q_full, b.x)
        y, z = seg.offset[0] + scale * V, seg.offset[1] + scale * W
        if np.any(b.K) or np.any(b.C):   # lateral: down from the shaft's underside
            springs.append(_spring(b.x, y, z - _depth(seg) / 2.0, size))
        else:                            # a thrust bearing (kxx alone): along -x from the axis
            springs.append(_spring(b.x, y, z, size).rotate_y(90.0, point=(b.x, y, z)))
    if springs:
        out["bearings"] = pv.merge(springs)
    cones = []
    for s in model.stack.supports:
        if {"V", "W"} & set(s.fix):
            seg = model.stack.segment(s.segment)
            top = seg.offset[1] - _depth(seg) / 2.0
            cones.append(pv.Cone(center=(s.x, seg.offset[0], top - 0.6 * size), direction=(0.0, 0.0, 1.0),
                                 height=1.2 * size, radius=0.6 * size, resolution=24))
    if cones:
        out["supports"] = pv.merge(cones)
    faces = crack_faces(model)
    if faces:
        _, _, owner = crack_geometry(model)
        ku, _ = crack_displacements(model, q_full)
        arcs = []
        for i, f in enumerate(faces):
            centre = np.asarray(model.stack.segment(f["segment"]).offset)
            yz = centre + 1.3 * (f["face"] - centre)   # the cracked part's outline, outside the surface
            p = np.column_stack([np.full(len(yz), f["x"]), yz]) + scale * ku[owner == i]
            arcs.append(pv.lines_from_points(p).tube(radius=0.15 * size))
            # and a thin collar around the whole section at x, seen from any side
            seg = model.stack.segment(f["segment"])
            a = np.linspace(0.0, 2.0 * np.pi, 49)
            ring = np.column_stack([np.full(a.size, f["x"]), centre[0] + 0.65 * seg.width * np.cos(a),
                                    centre[1] + 0.65 * _depth(seg) * np.sin(a)])
            arcs.append(pv.lines_from_points(ring + scale * ku[owner == i].mean(axis=0)).tube(radius=0.06 * size))
        out["cracks"] = pv.merge(arcs)
    return out


def render(result, model, T, path, time: float | None = None, exaggeration: float | None = None,
           window=(1400, 700)) -> Path:
    """Write a PNG of the rotor at the output time nearest ``time`` (default: the last one).

    ``exaggeration`` defaults to 10 % of the stack's length over the largest displacement.
    Returns the path written (atomically).
    """
    plotter = picture(result, model, T, time, exaggeration, window)
    img = plotter.screenshot(return_img=True)
    plotter.close()
    import matplotlib.image as mpimg

    return write_atomic(path, lambda tmp: mpimg.imsave(tmp, img, format="png"))


def picture(result, model, T, time: float | None = None, exaggeration: float | None = None, window=(1400, 700)):
    """The off-screen pyvista Plotter of :func:`render` (its arguments), before the screenshot: one actor per
    mesh of :func:`scene_meshes`, named like it, besides the bars, texts, axes and ruler."""
    os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    import pyvista as pv

    if result.t.size == 0:
        raise NsfemError("render: the result has no output times")
    k = result.t.size - 1 if time is None else int(np.argmin(np.abs(result.t - time)))
    if time is not None and not (result.t[0] - 1e-12 <= time <= result.t[-1] + 1e-12):
        raise NsfemError(f"render: --time {time} lies outside the result ({result.t[0]:g} to {result.t[-1]:g} s)")
    q_full = np.asarray(T @ result.q[:, k]).ravel()
    points, _, _, _ = stack_geometry(model)
    u = displacements(model, q_full)
    length = float(np.ptp(points[:, 0])) or 1.0
    umax = float(np.abs(u).max())
    if exaggeration is not None and not (math.isfinite(exaggeration) and exaggeration > 0):
        raise NsfemError(f"render: --exaggeration must be a finite positive number, got {exaggeration}")
    scale = exaggeration if exaggeration is not None else (0.1 * length / umax if umax > 0 else 1.0)
    if scale * umax > MAX_SHOWN * length:
        raise NsfemError(f"render: --exaggeration {scale:g} draws the largest displacement ({umax:.3g} m) as "
                         f"{scale * umax:.3g} m, more than {MAX_SHOWN:g} times the stack's length ({length:g} m): the "
                         f"picture would show nothing; at most {MAX_SHOWN * length / umax:.3g} here")
    meshes = scene_meshes(model, q_full, result.gap[:, k], scale)
    plotter = pv.Plotter(off_screen=True, window_size=list(window))
    plotter.add_mesh(meshes["stack"], scalars="u3 [mm]", cmap="coolwarm", show_edges=False, name="stack",
                     scalar_bar_args={"title": "vertical u3 [mm]", "vertical": True, **BAR, "position_x": 0.9})
    gaps = [meshes[n]["gap [mm]"] for n in ("stators", "contacts") if n in meshes]
    if gaps:
        clim = [float(min(g.min() for g in gaps)), float(max(g.max() for g in gaps))]
        clim[1] = clim[1] if clim[1] > clim[0] else clim[0] + 1e-9
        bar = {"title": "gap [mm]", "vertical": True, **BAR, "position_x": 0.03}
        for n in ("stators", "contacts"):
            if n in meshes:
                plotter.add_mesh(meshes[n], scalars="gap [mm]", cmap="viridis", clim=clim, scalar_bar_args=bar,
                                 opacity=0.85 if n == "stators" else 1.0, name=n)
    for n in ("disks", "bearings", "supports", "cracks"):
        if n in meshes:
            plotter.add_mesh(meshes[n], color=COLOURS[n], opacity=0.35 if n == "disks" else 1.0, name=n)
    legend = [LABELS[n] for n in ("disks", "stators", "bearings", "supports", "cracks") if n in meshes]
    if legend:
        # (right-justified at the window's edge: each line ends in two spaces, a margin)
        plotter.add_text("\n".join(f"{line}  " for line in legend), position="upper_right", font_size=9,
                         color="black")
    frame = result.info.get("frame", "rotating")
    # (a corner text starts at the window's very edge and loses its first letter: placed a margin inside)
    plotter.add_text(f"t = {result.t[k]:.4g} s, {frame} frame; displacements"
                     + (" and ring clearances" if "stators" in meshes else "") + f" drawn x {scale:.3g}", font_size=10,
                     position=(MARGIN, window[1] - MARGIN - 18))
    plotter.add_axes(xlabel="x (shaft)", ylabel="y", zlabel="z", line_width=3)
    bounds = np.array(pv.MultiBlock(list(meshes.values())).bounds).reshape(3, 2)
    below = bounds[2, 0] - 0.05 * length   # under everything, in front (it is drawn over the scene)
    plotter.add_ruler(pointa=(points[:, 0].min(), bounds[1, 0], below),
                      pointb=(points[:, 0].max(), bounds[1, 0], below),
                      title="x [m]", label_format="%.3g", number_labels=ruler_labels(float(np.ptp(points[:, 0]))),
                      font_size_factor=0.5)
    plotter.view_xz()
    plotter.camera.elevation = 20
    plotter.camera.azimuth = -25
    plotter.reset_camera()
    plotter.camera.zoom(1.25)   # the stack spans the middle of the width, clear of the bars, the ruler in view
    return plotter
