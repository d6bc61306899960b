"""Off-screen picture of the deformed beam stack at one output time (``nsfem render``).

pyvista draws the stack's solids (:func:`~nsfem.export.vtu.stack_geometry`) displaced by
``exaggeration`` times the beam kinematics, coloured by the vertical displacement u3, with the
contact points as spheres coloured by their gap (open: the gap in mm; closed: 0). It renders
without a display through VTK's EGL window (Mesa); ``VTK_DEFAULT_OPENGL_WINDOW`` is set to
``vtkEGLRenderWindow`` unless the user chose another (OSMesa builds of VTK work the same).
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np

from ..atomic import write_atomic
from ..errors import NsfemError
from .vtu import contact_points, displacements, stack_geometry


#: Colour bars: short, in the lower corners, narrow, beside the stack rather than over it
BAR = {"height": 0.4, "width": 0.04, "position_y": 0.06, "title_font_size": 16, "label_font_size": 14}
#: The largest drawn displacement, in stack lengths: beyond it the stack leaves the picture.
MAX_SHOWN = 10.0


def render(result, model, T, path, time: float | None = None, exaggeration: float | None = None,
           window=(1400, 700)) -> Path:
    """Write a PNG of the stack at the output time nearest ``time`` (default: the last one).

    ``exaggeration`` defaults to 10 % of the stack's length over the largest displacement.
    Returns the path written (atomically).
    """
    os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    import pyvista as pv

    if result.t.size == 0:
        raise NsfemError("render: the result has no output times")
    k = result.t.size - 1 if time is None else int(np.argmin(np.abs(result.t - time)))
    if time is not None and not (result.t[0] - 1e-12 <= time <= result.t[-1] + 1e-12):
        raise NsfemError(f"render: --time {time} lies outside the result ({result.t[0]:g} to {result.t[-1]:g} s)")
    q_full = np.asarray(T @ result.q[:, k]).ravel()
    points, cells, segment, _ = stack_geometry(model)
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
    grid = pv.UnstructuredGrid({pv.CellType.HEXAHEDRON: cells}, points + scale * u)
    grid.point_data["u3 [mm]"] = 1e3 * u[:, 2]
    plotter = pv.Plotter(off_screen=True, window_size=list(window))
    plotter.add_mesh(grid, scalars="u3 [mm]", cmap="coolwarm", show_edges=False,
                     scalar_bar_args={"title": "u3 [mm]", "vertical": True, **BAR, "position_x": 0.9})
    if result.gap.shape[0]:
        pos, du = contact_points(model, q_full)
        cloud = pv.PolyData(pos + scale * du)
        cloud.point_data["gap [mm]"] = 1e3 * result.gap[:, k]
        radius = 0.012 * length
        plotter.add_mesh(cloud.glyph(geom=pv.Sphere(radius=radius), scale=False, orient=False),
                         scalars="gap [mm]", cmap="viridis",
                         scalar_bar_args={"title": "gap [mm]", "vertical": True, **BAR, "position_x": 0.03})
    plotter.add_text(f"t = {result.t[k]:.4g} s, displacements x {scale:.3g}", font_size=10)
    plotter.view_xz()
    plotter.camera.elevation = 20
    plotter.camera.azimuth = -25
    plotter.reset_camera()
    plotter.camera.zoom(1.5)   # the stack spans the middle 3/4 of the width, clear of the bars
    img = plotter.screenshot(return_img=True)
    plotter.close()
    import matplotlib.image as mpimg

    return write_atomic(path, lambda tmp: mpimg.imsave(tmp, img, format="png"))
