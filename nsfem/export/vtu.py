"""VTU/PVD time series of a run: the beam stack as hexahedral solids, its contact points, disks, stator rings
and crack faces.

Every segment is drawn as its cross-section (a rectangle, width b along y and height h along
z; a circle as a polygon of 32 sides, hollow when it has a bore; centroid at its offset
(y_c, z_c) from the rotation axis) extruded along its line elements: one hexahedron per element
and quadrilateral of the section (four corners for a rectangle). The two sub-beams of a
delamination are therefore separate solids that touch along the interface plane, and an
opened gap shows as a visible slit.

Displacements are the Euler-Bernoulli kinematics of the model (the convention of
:mod:`nsfem.fem.rotating` and of the interface slip rows in :mod:`nsfem.contact.kinematics`):
at a section point (eta, zeta) from the segment's centroid axis

    u1 = U - eta V' - zeta W',   u2 = V,   u3 = W,

so a positive slope W' = dW/dx rotates the section such that points above the axis
(zeta > 0) move towards -x. The node values are exact; the solid between two sections is
the trilinear hexahedron, not the Hermite cubic.

The series is one ``<prefix>.pvd`` in the output folder indexing, by time, one ``<prefix>_NNNNN.vtm`` a
frame in its subfolder :data:`SUBFOLDER` (``vtu/``); the .vtm (VTK's multiblock file) names the frame's
parts as leaf blocks, each a .vtu beside it: ``stack`` (``<prefix>_NNNNN.vtu``, point data
``displacement``, cell data ``segment``), ``contacts`` when the model has any (``<prefix>_contacts_NNNNN.vtu``,
vertex cells, point data ``displacement``, ``gap``, ``normal_force``, ``tangential_force`` (3 components,
x y z), ``state``). A rotor with disks adds ``disks``, the disks as short cylinders
(``<prefix>_disks_NNNNN.vtu``, :func:`disk_geometry`: their geometry, or a steel cylinder of their mass and
polar inertia, :func:`disk_size`; point data ``displacement``, each disk moving rigidly with its node, cell
data ``disk``); one with stators ``stators``, the rings as polygons of their facets
(``<prefix>_stators_NNNNN.vtu``, :func:`stator_geometry`; point data ``displacement`` (0: fixed), one cell
per facet with cell data ``stator``, ``contact`` (its row in the contacts part and the result), ``gap``,
``normal_force``, ``tangential_force``, ``state``); one with cracks ``cracks``, each crack's face as a polygon
in the section plane at its x (``<prefix>_cracks_NNNNN.vtu``, :func:`crack_geometry`: the strip or circular
segment the crack has cut, moving with the left side's section; point data ``displacement`` and
``face_gap``, the faces' axial opening at that point; one cell per crack with cell data ``crack``,
``opening`` (the larger gap of its front's two contacts), ``state`` (how many of them are closed: 0 open,
1 partly closed, 2 closed) and ``normal_force`` (their sum)); one with bearings ``bearings``
(``<prefix>_bearings_NNNNN.vtu``, :func:`bearing_points`: a vertex on the shaft's axis at each bearing's x,
moving with it, point data ``displacement`` and the bearing's ``stiffness`` (kyy, kzz, kyz, kzy [N/m]),
``damping`` (cyy, czz, cyz, czy [N s/m]) and ``kxx`` [N/m]). Every part carries point data
``displacement``, so *Warp By Vector* applies to all of them; a comment in the .pvd says which frame the
coordinates are in and names the blocks. NNNNN is the index
of the output time in ``result.t``. Every file is written to a temporary name in the
output folder and renamed, so a reader never sees a half-written file; a series stopped part way
(Ctrl-C, SIGTERM, an error) still gets its ``.pvd``, indexing exactly the frames complete by then.

A stator ring is fixed in the frame the run was computed in (``result.info["frame"]``, as in the
model, :func:`nsfem.scene.stator_contacts`): in space for an inertial run; for a rotating-frame run
it is fixed in the rotating frame (where the polygon approximates the same circle), so it stands
still in the default rotating output and turns with the shaft in a ``frame="inertial"`` one. An
elastic ring (:mod:`nsfem.contact.ring`) is drawn at rest too: where the shaft is pushed beyond its
facet (gap < 0), the overlap of the drawn shaft and ring is its mount's compression.

>>> from nsfem import build_model, load_scene
>>> pts, cells, seg, book = stack_geometry(build_model(load_scene(None, ["mesh.elements=20"])))
>>> pts.shape == book.shape, cells.shape, int(seg.max())    # 4 segments; 16 elements under each sub-beam
(True, (36, 8), 3)
"""

from __future__ import annotations

import functools
import math
import re
from pathlib import Path
from typing import Callable, NamedTuple

import numpy as np

from ..atomic import signals_deferred, write_atomic
from ..contact.set import tangent_names
from ..errors import NsfemError

#: a stand-in for ``FEModel.dof``: (segment, field, x) -> the full-vector index
DofLookup = Callable[[str, str, float], int]
#: corner (eta, zeta) signs of a section, counter-clockwise seen from -x looking along +x
#: (so a hexahedron (section i, section i+1) has positive volume in VTK's ordering)
CORNERS = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])
_AXIS = {"x": 0, "y": 1, "z": 2}
#: the parts of a series after the stack, in their order in a frame (files ``<prefix>_<part>_NNNNN.vtu``)
PARTS = ("contacts", "disks", "stators", "cracks", "bearings")
#: the subfolder of the output folder that holds a series' frames (the .pvd stays at the top, beside the plots)
SUBFOLDER = "vtu"
#: the name of a frame file of a series (in :data:`SUBFOLDER`): a part's .vtu or the frame's .vtm
SERIES_FRAME = re.compile(r"^.+?((_(%s))?_\d{5,}\.vtu|_\d{5,}\.vtm)$" % "|".join(PARTS))


def _tangent_vector(contact, name: str) -> np.ndarray:
    """The unit vector of a contact's tangent direction ``name`` (an axis, or a stator facet's
    circumferential t = (0, -sin a, cos a))."""
    if name == "circumferential":
        return np.array([0.0, -math.sin(contact.angle), math.cos(contact.angle)])
    return np.eye(3)[_AXIS[name]]


#: a round section is drawn as a polygon of 2 SECTORS sides (its area 0.6 % short of the circle's at 16)
SECTORS = 16


def section_corners(seg) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(eta, zeta, quads) of a segment's section as drawn: its corner points and the quadrilaterals
    (k x 4 corner indices, counter-clockwise seen from -x) that tile it. A rectangle is one quad of
    its 4 corners (:data:`CORNERS`); a circle a 2 SECTORS-gon, tiled from its centre (solid: each quad is
    the centre and three consecutive vertices) or between its inner and outer polygons (hollow)."""
    if seg.section != "circle":
        return CORNERS[:, 0] * seg.width / 2.0, CORNERS[:, 1] * seg.height / 2.0, np.array([[0, 1, 2, 3]])
    m = 2 * SECTORS
    a = 2.0 * np.pi * np.arange(m) / m
    ring = np.column_stack([np.cos(a), np.sin(a)])
    R = seg.width / 2.0
    j = np.arange(m)
    if seg.inner > 0.0:   # outer vertices 0..m-1, inner m..2m-1
        pts = np.vstack([R * ring, seg.inner / 2.0 * ring])
        quads = np.column_stack([m + j, j, (j + 1) % m, m + (j + 1) % m])
    else:                 # vertices 0..m-1, the centre m
        pts = np.vstack([R * ring, [[0.0, 0.0]]])
        i = 2 * np.arange(SECTORS)
        quads = np.column_stack([np.full(SECTORS, m), i, (i + 1) % m, (i + 2) % m])
    return pts[:, 0], pts[:, 1], quads


def stack_geometry(model):
    """Hexahedral solids of every segment (round sections as polygons, :func:`section_corners`).

    Returns ``(points (P, 3), cells (C, 8), segment (C,), book (P, 3))``: ``book[p] =
    (segment index, node index, corner index)`` of point p, with p = base_s + k node + corner (k
    corners per section of that segment: 4 for a rectangle); cells follow VTK's hexahedron
    ordering (a quad of the section at node i, then the same at node i + 1).
    """
    pts, cells, seg_ids, book = [], [], [], []
    base = 0
    for s_idx, seg in enumerate(model.stack.segments):
        x = np.asarray(model.spaces[seg.name].x, dtype=float)
        n = x.size
        eta, zeta, quads = section_corners(seg)
        k = eta.size
        p = np.empty((n, k, 3))
        p[:, :, 0] = x[:, None]
        p[:, :, 1] = seg.offset[0] + eta[None, :]
        p[:, :, 2] = seg.offset[1] + zeta[None, :]
        pts.append(p.reshape(-1, 3))
        node, corner = np.meshgrid(np.arange(n), np.arange(k), indexing="ij")
        book.append(np.column_stack([np.full(k * n, s_idx), node.ravel(), corner.ravel()]))
        e = np.arange(n - 1)
        a = (base + k * e[:, None, None] + quads[None, :, :]).reshape(-1, 4)
        cells.append(np.hstack([a, a + k]))
        seg_ids.append(np.full((n - 1) * len(quads), s_idx))
        base += k * n
    return (np.vstack(pts), np.vstack(cells).astype(np.int64), np.concatenate(seg_ids).astype(np.int64),
            np.vstack(book).astype(np.int64))


def nodal_dofs(model, segment: str) -> dict[str, np.ndarray]:
    """Full-vector indices of U, V, V', W, W' at every mesh node of ``segment`` (each (n_nodes,))."""
    sp_ = model.spaces[segment]
    nd = sp_.bending.nodal_dofs
    return {"U": sp_.dofs["U"][sp_.axial.nodal_dofs[0]],
            "V": sp_.dofs["V"][nd[0]], "V'": sp_.dofs["V"][nd[1]],
            "W": sp_.dofs["W"][nd[0]], "W'": sp_.dofs["W"][nd[1]]}


def displacements(model, q_full) -> np.ndarray:
    """(P, 3) displacement of every point of :func:`stack_geometry` for the full dofs ``q_full``."""
    q_full = np.asarray(q_full, dtype=float).ravel()
    if q_full.size != model.n_full:
        raise NsfemError(f"export: q_full has {q_full.size} entries, the model {model.n_full}")
    out = []
    for seg in model.stack.segments:
        d = {k: q_full[v] for k, v in nodal_dofs(model, seg.name).items()}
        eta, zeta, _ = section_corners(seg)
        u = np.empty((d["U"].size, eta.size, 3))
        u[:, :, 0] = d["U"][:, None] - eta[None, :] * d["V'"][:, None] - zeta[None, :] * d["W'"][:, None]
        u[:, :, 1] = d["V"][:, None]
        u[:, :, 2] = d["W"][:, None]
        out.append(u.reshape(-1, 3))
    return np.vstack(out)


#: density [kg/m^3] of the steel cylinder a disk given by its mass and inertias is drawn as (:func:`disk_size`)
DISK_RHO = 7850.0
#: a stator ring is drawn RING_WIDTH times its inner radius (clearance + surface radius) wide along x and
#: RING_THICKNESS times it thick radially (the scene gives neither: the model's ring touches at one x)
RING_WIDTH = 1.0
RING_THICKNESS = 0.25


class _Round(NamedTuple):
    """A round section for :func:`section_corners` (outer diameter ``width``, bore ``inner``)."""

    width: float
    inner: float
    section: str = "circle"


def disk_size(disk) -> tuple[float, float, float]:
    """(outer diameter D, bore d, width w) [m] a :class:`~nsfem.stack.Disk` is drawn with.

    A disk given by its geometry (``[[disk]]`` ``outer_diameter``, ``inner_diameter``, ``width``) is drawn
    with it. A disk given by its mass m and polar inertia I_p is drawn as the solid steel cylinder (density
    :data:`DISK_RHO`) with that mass and polar inertia: I_p = m R^2 / 2 gives its radius R = sqrt(2 I_p / m),
    and m = rho pi R^2 w its width w = m / (rho pi R^2). Without a polar inertia (a point mass) it is the steel
    cylinder of mass m as wide as its diameter, D = w = (4 m / (rho pi))^(1/3). The diametral inertia is not
    used (a thin disk's I_d = I_p / 2 would give it no width).

    >>> from nsfem.stack import Disk
    >>> [round(v, 4) for v in disk_size(Disk(0.4, 5.0, polar=0.02))]    # the rub scene's disk
    [0.1789, 0.0, 0.0253]
    """
    if disk.outer_diameter > 0.0 and disk.width > 0.0:
        return float(disk.outer_diameter), float(disk.inner_diameter), float(disk.width)
    if disk.polar > 0.0:
        R = math.sqrt(2.0 * disk.polar / disk.mass)
        return 2.0 * R, 0.0, disk.mass / (DISK_RHO * math.pi * R * R)
    D = (4.0 * disk.mass / (DISK_RHO * math.pi)) ** (1.0 / 3.0)
    return D, 0.0, D


def _disk_centre(model, disk) -> tuple[str, np.ndarray]:
    """The segment carrying ``disk`` and the disk's centre (x, y_c, z_c) on that segment's centroid axis."""
    seg = model.stack.segment(model.stack.carrier(disk.x))
    return seg.name, np.array([disk.x, seg.offset[0], seg.offset[1]])


def disk_geometry(model):
    """Each disk as a short cylinder of :func:`disk_size`: its face the 2 SECTORS-gon of a round shaft
    (:func:`section_corners`, an annulus when it has a bore), centred on the carrying segment's centroid axis
    at the disk's x and extruded over its width (x - w/2 to x + w/2), one hexahedron per quadrilateral.

    Returns ``(points (P, 3), cells (C, 8), disk (C,), owner (P,))``: the disk index of each cell and point.
    """
    pts, cells, ids, owner = [np.zeros((0, 3))], [np.zeros((0, 8), dtype=np.int64)], [np.zeros(0, np.int64)], \
        [np.zeros(0, np.int64)]
    base = 0
    for i, d in enumerate(model.stack.disks):
        D, di, w = disk_size(d)
        eta, zeta, quads = section_corners(_Round(D, di))
        _, c = _disk_centre(model, d)
        k = eta.size
        p = np.empty((2, k, 3))
        p[0, :, 0], p[1, :, 0] = d.x - w / 2.0, d.x + w / 2.0
        p[:, :, 1] = c[1] + eta[None, :]
        p[:, :, 2] = c[2] + zeta[None, :]
        pts.append(p.reshape(-1, 3))
        cells.append(np.hstack([base + quads, base + k + quads]))
        ids.append(np.full(len(quads), i))
        owner.append(np.full(2 * k, i))
        base += 2 * k
    return (np.vstack(pts), np.vstack(cells).astype(np.int64), np.concatenate(ids).astype(np.int64),
            np.concatenate(owner).astype(np.int64))


def disk_displacements(model, q_full, dof: DofLookup | None = None) -> np.ndarray:
    """(P, 3) displacement of every point of :func:`disk_geometry`: each disk moves rigidly with its node,
    translated by (U, V, W) and tilted by the slopes; at (xi, eta, zeta) from its centre

        u1 = U - eta V' - zeta W',   u2 = V + xi V',   u3 = W + xi W'

    (the small rotation whose section part is the shaft's u1 of :func:`displacements`).
    ``dof``: in place of ``model.dof`` (:func:`write_series` passes a cached one)."""
    q_full = np.asarray(q_full, dtype=float).ravel()
    dof = dof or model.dof
    pts, _, _, owner = disk_geometry(model)
    u = np.zeros_like(pts)
    for i, d in enumerate(model.stack.disks):
        seg, c = _disk_centre(model, d)
        U, V, W, Vp, Wp = (q_full[dof(seg, f, d.x)] for f in ("U", "V", "W", "V'", "W'"))
        sel = owner == i
        xi, eta, zeta = (pts[sel] - c).T
        u[sel] = np.column_stack([U - eta * Vp - zeta * Wp, V + xi * Vp, W + xi * Wp])
    return u


def stator_rings(model) -> list[dict]:
    """The model's stator rings: its facets (obstacles with an ``angle``) grouped by ring (the
    ``stator.<i>`` of their labels, else by x, segment, clearance and radius), each ring that closes
    (3 or more facets, no gap of pi or more between neighbouring normals) as a dict: ``label``, ``x``,
    ``centre`` (y, z) (the carrying segment's centroid axis, where the gap is measured from), ``radius``
    (clearance + the surface radius: the distance of every facet from the centre), ``clearance`` and
    ``surface`` (the two terms), ``contacts`` (the facets' contact indices ordered by angle) and ``angles``."""
    groups: dict[tuple, list[int]] = {}
    for k, c in enumerate(model.stack.contacts):
        if c.angle is None:
            continue
        parts = c.label.split(".")
        ring = ".".join(parts[:2]) if len(parts) == 3 and parts[0] == "stator" else ""
        groups.setdefault((ring, c.x, c.segments[0], c.clearance, c.radius), []).append(k)
    rings = []
    for (ring, x, seg, clearance, radius), ks in groups.items():
        a = np.array([model.stack.contacts[k].angle for k in ks]) % (2.0 * math.pi)
        order = np.argsort(a, kind="stable")
        a = a[order]
        if a.size < 3 or np.diff(np.append(a, a[0] + 2.0 * math.pi)).max() >= math.pi:
            continue
        rings.append({"label": ring or model.stack.contacts[ks[0]].label, "x": x,
                      "centre": model.stack.segment(seg).offset, "radius": clearance + radius,
                      "clearance": clearance, "surface": radius, "contacts": np.asarray(ks)[order], "angles": a})
    return rings


def stator_geometry(model, clearance_scale: float = 1.0, width: float | None = None):
    """Each stator ring (:func:`stator_rings`) as the polygon the model has: facet k is the plane
    n_k . (y, z) = clearance + radius from the ring's centre (n_k = (cos a_k, sin a_k)), so that the shaft
    surface touches it when its gap is 0; neighbouring facets meet at the corners, at the angle halfway
    between their normals and (clearance + radius) / cos(half the angle between them) from the centre
    (for ``facets`` equal sides at (2 k + 1) pi / facets, (clearance + radius) / cos(pi / facets)). The ring
    is :data:`RING_THICKNESS` of its inner radius thick (its outer facets parallel to the inner ones) and
    :data:`RING_WIDTH` of it wide, centred at x: one hexahedron per facet.

    ``clearance_scale`` draws the clearance that many times as wide (surface + scale x clearance from the
    centre; :mod:`nsfem.export.render` scales it with the displacements, so that the drawn shaft touches the
    drawn ring where the gap closes); ``width`` [m] replaces the RING_WIDTH rule.

    Returns ``(points (P, 3), cells (C, 8), ring (C,), contact (C,))``: the ring index and the contact index
    (the row of the result's gap, forces and state) of each facet's cell.
    """
    pts, cells, ids, cons = [np.zeros((0, 3))], [np.zeros((0, 8), dtype=np.int64)], [np.zeros(0, np.int64)], \
        [np.zeros(0, np.int64)]
    base = 0
    for i, r in enumerate(stator_rings(model)):
        a = r["angles"]
        n = a.size
        nxt = np.append(a[1:], a[0] + 2.0 * math.pi)
        phi, half = (a + nxt) / 2.0, (nxt - a) / 2.0    # corner j: between facets j and j + 1
        inner = r["radius"] if clearance_scale == 1.0 else r["surface"] + clearance_scale * r["clearance"]
        rad = np.concatenate([inner / np.cos(half), inner * (1.0 + RING_THICKNESS) / np.cos(half)])
        ang = np.concatenate([phi, phi])                 # inner corners 0..n-1, outer n..2n-1
        w = RING_WIDTH * inner if width is None else width
        p = np.empty((2, 2 * n, 3))
        p[0, :, 0], p[1, :, 0] = r["x"] - w / 2.0, r["x"] + w / 2.0
        p[:, :, 1] = r["centre"][0] + rad * np.cos(ang)
        p[:, :, 2] = r["centre"][1] + rad * np.sin(ang)
        pts.append(p.reshape(-1, 3))
        j = np.arange(n)
        prev = (j - 1) % n                               # facet j runs from corner j - 1 to corner j
        quad = base + np.column_stack([prev, n + prev, n + j, j])
        cells.append(np.hstack([quad, quad + 2 * n]))
        ids.append(np.full(n, i))
        cons.append(r["contacts"])
        base += 4 * n
    return (np.vstack(pts), np.vstack(cells).astype(np.int64), np.concatenate(ids).astype(np.int64),
            np.concatenate(cons).astype(np.int64))


#: a round section's crack face is drawn with its arc as CRACK_ARC equal chords (the drawn segment's area is then
#: within 1e-3 of the circular segment's for any depth up to 0.8: 1 / CRACK_ARC^2 for a shallow crack)
CRACK_ARC = 4 * SECTORS


def crack_faces(model) -> list[dict]:
    """Each crack of the model (:class:`~nsfem.stack.Crack`) as drawn: the crack face, the part of the section
    at the crack's x that the crack has cut (a rectangle: the strip of depth a along the face ``side``, across
    the whole section; a circle: the circular segment of height a, its arc :data:`CRACK_ARC` chords),
    counter-clockwise in the (y, z) plane.

    Each entry: ``label``, ``x``, ``segment`` (the left side, whose node the face moves with), ``face`` (k, 2):
    the vertices (y, z) from the axis, the first and last the ends of the crack front (where the crack's
    contact points are, :func:`nsfem.fem.crack.face_points`); ``centre`` (y, z): the ligament's centroid (the
    hinge's centre, the contacts' arms start there); ``contacts``: the rows of the front's contacts, in the
    order of their labels.
    """
    from ..fem.crack import SIDE_DIRECTION, ligament_centroid

    out = []
    for k in model.stack.cracks:
        seg = model.stack.segment(k.segments[0])
        dy, dz = SIDE_DIRECTION[k.side]
        H, B = (seg.width, seg.height) if dy else (seg.height, seg.width)   # depth side, front side
        a = k.depth * H
        if seg.section == "circle":
            R = H / 2.0
            psi = math.acos(1.0 - a / R)
            phi = np.linspace(-psi, psi, CRACK_ARC + 1)
            s, t = R * np.cos(phi), R * np.sin(phi)
            s[[0, -1]] = R - a                  # the front's ends exactly (cos psi = 1 - a / R)
        else:
            s, t = np.array([H / 2.0 - a, H / 2.0, H / 2.0, H / 2.0 - a]), np.array([-B, -B, B, B]) / 2.0
        # s along the depth direction d (towards the cracked face), t along the front d turned by +90 degrees
        face = np.column_stack([s * dy - t * dz, s * dz + t * dy]) + np.asarray(seg.offset)
        rows = [j for j, c in enumerate(model.stack.contacts)
                if c.kind == "crack" and c.segments == k.segments and c.x == k.x]
        rows.sort(key=lambda j: model.stack.contacts[j].label)
        centre = ligament_centroid(seg.section, H, k.depth) * np.array([dy, dz]) + np.asarray(seg.offset)
        out.append({"label": k.label, "x": k.x, "segment": seg.name, "face": face, "centre": centre,
                    "contacts": np.asarray(rows, dtype=np.int64)})
    return out


def crack_geometry(model):
    """The crack faces of :func:`crack_faces` as polygons in the section plane at each crack's x.

    Returns ``(points (P, 3), polygons, owner (P,))``: ``polygons[i]`` the (k_i,) point indices of crack i's
    face (one polygon cell each), ``owner`` the crack index of each point.
    """
    pts, polys, owner = [np.zeros((0, 3))], [], [np.zeros(0, np.int64)]
    base = 0
    for i, f in enumerate(crack_faces(model)):
        k = len(f["face"])
        pts.append(np.column_stack([np.full(k, f["x"]), f["face"]]))
        polys.append(base + np.arange(k, dtype=np.int64))
        owner.append(np.full(k, i))
        base += k
    return np.vstack(pts), polys, np.concatenate(owner).astype(np.int64)


def crack_displacements(model, q_full, dof: DofLookup | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(displacement (P, 3), face_gap (P,)) of every point of :func:`crack_geometry`.

    The face moves with the left side's section at x: at (eta, zeta) from the centroid u1 = U - eta V' -
    zeta W', u2 = V, u3 = W (:func:`displacements`). ``face_gap`` is the faces' axial opening there,
    -(y dV' + z dW') with (y, z) from the ligament's centroid and d the right side's slope less the left's
    (the crack contacts' gap, :func:`nsfem.contact.kinematics.contact_row`): at the front's ends it is their
    gaps, and it grows towards the crack's mouth when the crack opens.
    ``dof``: in place of ``model.dof`` (:func:`write_series` passes a cached one).
    """
    q_full = np.asarray(q_full, dtype=float).ravel()
    dof = dof or model.dof
    pts, _, owner = crack_geometry(model)
    u, gap = np.zeros_like(pts), np.zeros(len(pts))
    for i, (k, f) in enumerate(zip(model.stack.cracks, crack_faces(model))):
        (left, right), x = k.segments, k.x
        U, V, W, Vp, Wp = (q_full[dof(left, n, x)] for n in ("U", "V", "W", "V'", "W'"))
        dVp, dWp = (q_full[dof(right, n, x)] - q_full[dof(left, n, x)] for n in ("V'", "W'"))
        sel = owner == i
        eta, zeta = (pts[sel, 1:] - model.stack.segment(left).offset).T
        u[sel] = np.column_stack([U - eta * Vp - zeta * Wp, np.full(eta.size, V), np.full(eta.size, W)])
        y, z = (pts[sel, 1:] - f["centre"]).T
        gap[sel] = -(y * dVp + z * dWp)
    return u, gap


def crack_data(result, faces, i: int) -> dict[str, np.ndarray]:
    """Per crack of ``faces`` (:func:`crack_faces`) at output index i: ``opening`` (the largest gap of the
    front's contacts), ``state`` (how many of them are closed: 0 open, 1 partly closed, 2 closed),
    ``normal_force`` (their sum: the compressive force across the faces)."""
    rows = [f["contacts"] for f in faces]
    return {"opening": np.array([result.gap[r, i].max() for r in rows], dtype=float),
            "state": np.array([int((result.state[r, i] != 0).sum()) for r in rows], dtype=np.int32),
            "normal_force": np.array([result.normal_force[r, i].sum() for r in rows], dtype=float)}


def bearing_points(model, q_full, dof: DofLookup | None = None) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
    """(positions (b, 3), displacements (b, 3), point data) of the bearings: each on the centroid axis of
    the segment carrying its x, moving with the shaft there (U, V, W); point data ``stiffness`` and
    ``damping`` (b, 4): yy, zz, yz, zy, and ``kxx`` (b,).
    ``dof``: in place of ``model.dof`` (:func:`write_series` passes a cached one)."""
    q_full = np.asarray(q_full, dtype=float).ravel()
    dof = dof or model.dof
    pos, disp, k, c, kxx = [], [], [], [], []
    for b in model.stack.bearings:
        name = model.stack.carrier(b.x) or next(s.name for s in model.stack.segments if s.start <= b.x <= s.end)
        off = model.stack.segment(name).offset
        pos.append([b.x, off[0], off[1]])
        disp.append([q_full[dof(name, f, b.x)] for f in ("U", "V", "W")])
        (kyy, kyz), (kzy, kzz) = b.K
        (cyy, cyz), (czy, czz) = b.C
        k.append([kyy, kzz, kyz, kzy])
        c.append([cyy, czz, cyz, czy])
        kxx.append(b.kxx)
    data = {"stiffness": np.array(k, dtype=float).reshape(-1, 4), "damping": np.array(c, dtype=float).reshape(-1, 4),
            "kxx": np.array(kxx, dtype=float)}
    return np.array(pos, dtype=float).reshape(-1, 3), np.array(disp, dtype=float).reshape(-1, 3), data


def rotation(angle: float) -> np.ndarray:
    """Rotation about +x by ``angle`` [rad]: rotating-frame vectors to inertial ones."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def contact_points(model, q_full, dof: DofLookup | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Positions (m, 3) and displacements (m, 3) of the contact points.

    Interface: on the interface plane (bottom face of the upper sub-beam) at y = y_c, with
    the mean displacement of the two touching faces there. Obstacle: the centroid of the
    carrying segment (where its gap is measured) and its displacement (U, V, W). A stator's
    facet: the shaft surface point it faces, at the facet's radius R along its normal n, with that
    point's displacement (U - R n.(V', W'), V, W): the gap is then the clearance less n.(its
    displacement), measured from the surface the ring sees. A crack face's point: its end of the crack
    front in the section at x (its arm from the ligament's centroid, :func:`crack_faces`), with the mean
    of the two sides' displacements (U - eta V' - zeta W', V, W) there.
    ``dof``: in place of ``model.dof`` (:func:`write_series` passes a cached one).
    """
    q_full = np.asarray(q_full, dtype=float).ravel()
    dof = dof or model.dof
    centres = {(k.segments, k.x): f["centre"] for k, f in zip(model.stack.cracks, crack_faces(model))}
    pos, disp = [], []
    for c in model.stack.contacts:
        if c.kind == "crack":
            yz = centres[(c.segments, c.x)] + np.asarray(c.arm)
            us = []
            for name in c.segments:
                eta, zeta = yz - model.stack.segment(name).offset
                U, V, W, Vp, Wp = (q_full[dof(name, f, c.x)] for f in ("U", "V", "W", "V'", "W'"))
                us.append([U - eta * Vp - zeta * Wp, V, W])
            pos.append([c.x, yz[0], yz[1]])
            disp.append(np.mean(us, axis=0))
            continue
        if c.angle is not None:
            s = model.stack.segment(c.segments[0])
            n = np.array([math.cos(c.angle), math.sin(c.angle)])
            U, V, W, Vp, Wp = (q_full[dof(s.name, f, c.x)] for f in ("U", "V", "W", "V'", "W'"))
            pos.append([c.x, s.offset[0] + c.radius * n[0], s.offset[1] + c.radius * n[1]])
            disp.append([U - c.radius * (n[0] * Vp + n[1] * Wp), V, W])
            continue
        segs = [model.stack.segment(n) for n in c.segments]
        us = []
        for k, s in enumerate(segs):
            zeta = (-s.height / 2.0 if k == 0 else s.height / 2.0) if c.kind == "interface" else 0.0
            U, W, Wp = (q_full[dof(s.name, f, c.x)] for f in ("U", "W", "W'"))
            us.append([U - zeta * Wp, q_full[dof(s.name, "V", c.x)], W])
        up = segs[0]
        z = up.offset[1] - up.height / 2.0 if c.kind == "interface" else up.offset[1]
        pos.append([c.x, up.offset[0], z])
        disp.append(np.mean(us, axis=0))
    return np.array(pos, dtype=float).reshape(-1, 3), np.array(disp, dtype=float).reshape(-1, 3)


def _model_and_T(system_or_model_and_T):
    if isinstance(system_or_model_and_T, tuple):
        model, T = system_or_model_and_T
        return model, T, None
    info = system_or_model_and_T.info
    system = system_or_model_and_T
    return info["model"], info["reduction"].T, getattr(system, "model_contacts", getattr(system, "contacts", None))


def series_files(n_times: int, every: int, prefix: str = "nsfem", parts=PARTS) -> list[str]:
    """The names (relative to the output folder) a series of ``n_times`` output times may write: its
    .pvd at the top and, in :data:`SUBFOLDER`, for every ``every``-th time the stack's frame, one per
    part of ``parts`` and the frame's .vtm that names them."""
    names = [f"{prefix}.pvd"]
    for i in range(0, n_times, every):
        names += ([f"{SUBFOLDER}/{prefix}_{i:05d}.vtu"] + [f"{SUBFOLDER}/{prefix}_{p}_{i:05d}.vtu" for p in parts]
                  + [f"{SUBFOLDER}/{prefix}_{i:05d}.vtm"])
    return names


#: bytes of a VTU file besides its arrays (XML header, array descriptions: 1.2 to 1.9 kB measured)
VTU_OVERHEAD = 2048
#: bytes of a frame's .vtm (0.4 to 0.6 kB measured for 2 to 5 parts)
VTM_BYTES = 1024


def frame_size(model) -> tuple[int, float]:
    """(files, bytes) of one frame of ``model``'s series: its parts and its .vtm. The bytes are an upper
    bound (every array in meshio's raw binary, 8 bytes a value, as base64, before its zlib compression,
    which gains 2x to 5x on these files; plus :data:`VTU_OVERHEAD` a file and the .vtm)."""
    points, cells, _, _ = stack_geometry(model)
    dpoints, dcells, _, _ = disk_geometry(model)
    spoints, scells, _, _ = stator_geometry(model)
    cpoints, cpolys, _ = crack_geometry(model)
    m = len(model.stack.contacts)
    # values per part: coordinates and displacements (6 a point), connectivity, offsets and types,
    # then the point / cell data of write_series
    values = [6 * len(points) + cells.size + 3 * len(cells)]
    if m:
        values.append(15 * m)
    if len(dcells):
        values.append(6 * len(dpoints) + dcells.size + 3 * len(dcells))
    if len(scells):
        values.append(6 * len(spoints) + scells.size + 10 * len(scells))
    if len(cpolys):
        values.append(7 * len(cpoints) + sum(len(p) for p in cpolys) + 6 * len(cpolys))
    if model.stack.bearings:
        values.append(18 * len(model.stack.bearings))
    return len(values) + 1, float(sum(8 * 4 / 3 * v + VTU_OVERHEAD for v in values) + VTM_BYTES)


def _write_vtu(path: Path, mesh) -> None:
    import meshio

    write_atomic(path, lambda tmp: meshio.write(tmp, mesh, file_format="vtu"))


def series_frame(result, frame: str | None) -> tuple[str, bool]:
    """(the frame a series of ``result`` is written in, whether its coordinates are turned to it): ``frame``
    None keeps the run's (``result.info["frame"]``); "inertial" turns a rotating-frame run's coordinates by
    Omega t + phase. A run computed in the inertial frame cannot be written in the rotating one (its stators
    are fixed in space, and the series would need them turned back): refused, as is any other name."""
    computed = result.info.get("frame", "rotating")
    if frame is None:
        return computed, False
    if frame not in ("rotating", "inertial"):
        raise NsfemError(f"export: frame must be rotating | inertial, got {frame!r}")
    if frame == "rotating" and computed == "inertial":
        raise NsfemError("export: the run was computed in the inertial frame (rotation.frame = \"inertial\"); its "
                         "series is written in that frame only: leave out the rotating frame")
    return frame, frame != computed


def write_series(result, system_or_model_and_T, out_dir, every: int = 10, frame: str | None = None,
                 prefix: str = "nsfem", phase_deg: float | None = None) -> Path:
    """Write the VTU series of a run and its ``<prefix>.pvd`` index; returns the .pvd path.

    The .pvd is written in ``out_dir``, the frames in its subfolder :data:`SUBFOLDER`: per output time
    written, one .vtu per part and a .vtm that names them (``stack``, ``contacts``, ``disks``, ``stators``,
    ``cracks``, ``bearings``: a part the model lacks, contacts included, is left out), which the .pvd indexes by time
    (paths relative to it, so the folder can be moved whole).

    ``system_or_model_and_T`` is the ContactSystem of :func:`nsfem.simulate.run_scene` or a
    tuple ``(model, T)`` with q_full = T q (e.g. a rebuilt model and the results file's
    ``basis``). Every ``every``-th output time is written (indices 0, every, 2 every, ...).
    ``frame`` (:func:`series_frame`): None writes the run's frame; ``"inertial"`` turns a rotating-frame
    run's points and displacements about x by Omega t + phase (Omega = 2 pi ``result.info["speed_hz"]``; a run-up's
    theta(t), the integral of its speed;
    ``phase_deg`` as ``rotation.phase_deg``, the frame in which gravity points along -z, by default the
    run's, ``result.info["phase_deg"]``). A model with disks, stators, cracks or bearings gets their parts too
    (:func:`disk_geometry`, :func:`stator_geometry`, :func:`crack_geometry`, :func:`bearing_points`; the
    module's docstring lists the parts). Interrupted (KeyboardInterrupt) or failing part way, it removes the frame it was
    writing, writes the .pvd of the frames before it and re-raises.
    """
    import meshio

    written, turn = series_frame(result, frame)
    if not (isinstance(every, int) and every >= 1):
        raise NsfemError(f"export: every must be a positive integer, got {every!r}")
    model, T, contacts = _model_and_T(system_or_model_and_T)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    sub = out / SUBFOLDER   # created by the first frame's write
    points, cells, seg_ids, _ = stack_geometry(model)
    dpoints, dcells, disk_ids, _ = disk_geometry(model)
    spoints, scells, ring_ids, facet_contact = stator_geometry(model)
    cpoints, cpolys, _ = crack_geometry(model)
    faces = crack_faces(model)
    omega = 2.0 * math.pi * float(result.info.get("speed_hz", 0.0)) if turn else 0.0
    # a run-up's frame turns by the integral of its speed (nsfem.sensors.frame_angle)
    from ..sensors import frame_angle, speed_table

    table = speed_table(result.info)
    ramp = (result.info.get("ramp_to_hz"), float(result.info.get("ramp_s", 0.0)), table) \
        if turn and (result.info.get("ramp_to_hz") is not None or table is not None) else None
    if phase_deg is None:
        phase_deg = float(result.info.get("phase_deg", 0.0))
    phase = math.radians(phase_deg) if turn else 0.0
    m = result.gap.shape[0]
    stack_contacts = model.stack.contacts
    if len(stack_contacts) != m:
        raise NsfemError(f"export: the result has {m} contacts, the model {len(stack_contacts)}")
    tangents = []   # per contact: the unit vector (x, y, z) of each tangent direction of its force
    for k, c in enumerate(stack_contacts):
        names = contacts.tangents[k] if contacts is not None else tangent_names(c)
        tangents.append([_tangent_vector(c, name) for name in names[:2]])
    idx = list(range(0, result.t.size, every))
    dof = functools.lru_cache(maxsize=None)(model.dof)   # every frame looks up the same dofs (2 us each)
    entries: list[tuple[float, str]] = []
    nb = len(model.stack.bearings)
    blocks = (["stack"] + ["contacts"] * bool(m) + ["disks"] * bool(len(dcells)) + ["stators"] * bool(len(scells))
              + ["cracks"] * bool(faces) + ["bearings"] * bool(nb))
    pvd = out / f"{prefix}.pvd"
    files: list[str] = []
    indexed: Path | None = None   # the .pvd, once written
    try:
        for i in idx:
            files = []
            q_full = np.asarray(T @ result.q[:, i]).ravel()
            u = displacements(model, q_full)
            cpos, cdisp = contact_points(model, q_full, dof)
            tf = np.zeros((m, 3))
            for k in range(m):
                for j, vec in enumerate(tangents[k]):
                    tf[k] += result.tangential_force[k, j, i] * vec
            du = disk_displacements(model, q_full, dof)
            ku, kgap = crack_displacements(model, q_full, dof)
            bpos, bdisp, bdata = bearing_points(model, q_full, dof)
            p, dp, sp_, kp = points, dpoints, spoints, cpoints
            if turn:
                R = rotation(omega * float(result.t[i]) + phase if ramp is None
                             else float(frame_angle(result.t[i], omega / (2.0 * math.pi), 0.0, *ramp)) + phase)
                p, u, cpos, cdisp, tf, dp, du, sp_, kp, ku, bpos, bdisp = (
                    a @ R.T for a in (points, u, cpos, cdisp, tf, dpoints, du, spoints, cpoints, ku, bpos, bdisp))
            files.append(f"{prefix}_{i:05d}.vtu")
            _write_vtu(sub / files[-1], meshio.Mesh(p, [("hexahedron", cells)], point_data={"displacement": u},
                                                    cell_data={"segment": [seg_ids]}))
            if m:
                files.append(f"{prefix}_contacts_{i:05d}.vtu")
                vert = np.arange(m, dtype=np.int64).reshape(-1, 1)
                _write_vtu(sub / files[-1], meshio.Mesh(
                    cpos, [("vertex", vert)],
                    point_data={"displacement": cdisp, "gap": np.asarray(result.gap[:, i], dtype=float),
                                "normal_force": np.asarray(result.normal_force[:, i], dtype=float),
                                "tangential_force": tf, "state": np.asarray(result.state[:, i], dtype=np.int32)}))
            if len(dcells):
                files.append(f"{prefix}_disks_{i:05d}.vtu")
                _write_vtu(sub / files[-1], meshio.Mesh(dp, [("hexahedron", dcells)], point_data={"displacement": du},
                                                        cell_data={"disk": [disk_ids]}))
            if len(scells):
                files.append(f"{prefix}_stators_{i:05d}.vtu")
                fc = facet_contact
                _write_vtu(sub / files[-1], meshio.Mesh(
                    sp_, [("hexahedron", scells)], point_data={"displacement": np.zeros_like(sp_)},
                    cell_data={"stator": [ring_ids], "contact": [fc],
                               "gap": [np.asarray(result.gap[fc, i], dtype=float)],
                               "normal_force": [np.asarray(result.normal_force[fc, i], dtype=float)],
                               "tangential_force": [tf[fc]], "state": [np.asarray(result.state[fc, i], dtype=np.int32)]}))
            if faces:
                files.append(f"{prefix}_cracks_{i:05d}.vtu")
                data = crack_data(result, faces, i)
                _write_vtu(sub / files[-1], meshio.Mesh(
                    kp, [("polygon", poly[None, :]) for poly in cpolys], point_data={"displacement": ku, "face_gap": kgap},
                    cell_data={"crack": [np.array([j]) for j in range(len(faces))],
                               **{n: [v[j:j + 1] for j in range(len(faces))] for n, v in data.items()}}))
            if nb:
                files.append(f"{prefix}_bearings_{i:05d}.vtu")
                vert = np.arange(nb, dtype=np.int64).reshape(-1, 1)
                _write_vtu(sub / files[-1], meshio.Mesh(bpos, [("vertex", vert)],
                                                        point_data={"displacement": bdisp, **bdata}))
            vtm = f"{prefix}_{i:05d}.vtm"
            parts = list(zip(blocks, files))
            files.append(vtm)
            write_vtm(sub / vtm, parts)
            with signals_deferred():  # the frame is whole: indexed, and no longer one to remove
                entries.append((float(result.t[i]), f"{SUBFOLDER}/{vtm}"))
                files = []
        with signals_deferred():  # Ctrl-C on the index itself is acted on once it is written
            indexed = write_pvd(pvd, entries, blocks, written, turn, prefix)
    except BaseException:  # interrupted (or failed): the frames written so far stay a valid series
        if indexed is None:
            with signals_deferred():
                for f in files:  # the frame cut short; never a folder of that name, which made the write fail
                    if not (sub / f).is_dir():
                        (sub / f).unlink(missing_ok=True)
                write_pvd(pvd, entries, blocks, written, turn, prefix)
        raise
    return indexed


def write_vtm(path: Path, blocks: list[tuple[str, str]]) -> Path:
    """A frame's ``.vtm`` (VTK's multiblock file): one named leaf block per (name, file in its folder)."""
    from xml.sax.saxutils import quoteattr  # here: it loads urllib, http and ssl (25 ms) into every run

    lines = ['<?xml version="1.0"?>',
             '<VTKFile type="vtkMultiBlockDataSet" version="1.0" byte_order="LittleEndian">',
             "  <vtkMultiBlockDataSet>"]
    lines += [f'    <DataSet index="{k}" name={quoteattr(name)} file={quoteattr(f)}/>'
              for k, (name, f) in enumerate(blocks)]
    lines += ["  </vtkMultiBlockDataSet>", "</VTKFile>", ""]
    return write_atomic(path, lambda tmp: Path(tmp).write_text("\n".join(lines), encoding="utf-8"))


def write_pvd(pvd: Path, entries: list[tuple[float, str]], blocks: list[str], written: str, turn: bool,
              prefix: str = "nsfem") -> Path:
    """The ``.pvd`` index of the frames ``entries`` [(t, the frame's .vtm relative to the .pvd)], whose
    blocks are ``blocks``."""
    from xml.sax.saxutils import quoteattr

    note = (" (it turns with the shaft at Omega; stator rings are fixed in it, as in the model)" if written == "rotating"
            else " (turned from the run's rotating frame by Omega t + phase: its stator rings, fixed in that frame "
            "in the model, turn with it)" if turn else "")
    lines = ['<?xml version="1.0"?>',
             '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">',
             f"  <!-- nsfem: coordinates in the {written} frame{note}; each time a .vtm in {SUBFOLDER}/ with the "
             "blocks " + ", ".join(blocks) + " -->",
             "  <Collection>"]
    lines += [f'    <DataSet timestep="{t!r}" group="" part="0" name={quoteattr(prefix)} file={quoteattr(f)}/>'
              for t, f in entries]
    lines += ["  </Collection>", "</VTKFile>", ""]
    write_atomic(pvd, lambda tmp: Path(tmp).write_text("\n".join(lines), encoding="utf-8"))
    return pvd


def series_parts(pvd) -> dict[str, list[tuple[float, str]]]:
    """{block name: [(time, its .vtu relative to the .pvd's folder), ...]} of a series written by
    :func:`write_series` (the .pvd and the .vtm of each time it indexes)."""
    import posixpath
    import xml.etree.ElementTree as ET

    pvd = Path(pvd)
    out: dict[str, list[tuple[float, str]]] = {}
    for d in ET.parse(pvd).getroot().iter("DataSet"):
        t, vtm = float(d.get("timestep")), d.get("file")
        for b in ET.parse(pvd.parent / vtm).getroot().iter("DataSet"):
            out.setdefault(b.get("name"), []).append((t, posixpath.join(posixpath.dirname(vtm), b.get("file"))))
    return out
