"""VTU/PVD time series of a run: the beam stack as hexahedral solids, and its contact points.

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

The series is one ``.pvd`` with two parts: part 0 the stack (``<prefix>_NNNNN.vtu``, point
data ``displacement``, cell data ``segment``), part 1 the contact points
(``<prefix>_contacts_NNNNN.vtu``, vertex cells, point data ``displacement``, ``gap``,
``normal_force``, ``tangential_force`` (3 components, x y z), ``state``). NNNNN is the index
of the output time in ``result.t``. Every file is written to a temporary name in the
output folder and renamed, so a reader never sees a half-written file.

>>> from nsfem import build_model, load_scene
>>> pts, cells, seg, book = stack_geometry(build_model(load_scene(None, ["mesh.elements=20"])))
>>> pts.shape == book.shape, cells.shape, int(seg.max())    # 4 segments; 16 elements under each sub-beam
(True, (36, 8), 3)
"""

from __future__ import annotations

import math
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np

from ..atomic import write_atomic
from ..contact.set import tangent_names
from ..errors import NsfemError

#: corner (eta, zeta) signs of a section, counter-clockwise seen from -x looking along +x
#: (so a hexahedron (section i, section i+1) has positive volume in VTK's ordering)
CORNERS = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])
_AXIS = {"x": 0, "y": 1, "z": 2}


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


def rotation(angle: float) -> np.ndarray:
    """Rotation about +x by ``angle`` [rad]: rotating-frame vectors to inertial ones."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def contact_points(model, q_full) -> tuple[np.ndarray, np.ndarray]:
    """Positions (m, 3) and displacements (m, 3) of the contact points.

    Interface: on the interface plane (bottom face of the upper sub-beam) at y = y_c, with
    the mean displacement of the two touching faces there. Obstacle: the centroid of the
    carrying segment (where its gap is measured) and its displacement (U, V, W). A stator's
    facet: the shaft surface point it faces, at the facet's radius R along its normal n, with that
    point's displacement (U - R n.(V', W'), V, W): the gap is then the clearance less n.(its
    displacement), measured from the surface the ring sees.
    """
    q_full = np.asarray(q_full, dtype=float).ravel()
    pos, disp = [], []
    for c in model.stack.contacts:
        if c.angle is not None:
            s = model.stack.segment(c.segments[0])
            n = np.array([math.cos(c.angle), math.sin(c.angle)])
            U, V, W, Vp, Wp = (q_full[model.dof(s.name, f, c.x)] for f in ("U", "V", "W", "V'", "W'"))
            pos.append([c.x, s.offset[0] + c.radius * n[0], s.offset[1] + c.radius * n[1]])
            disp.append([U - c.radius * (n[0] * Vp + n[1] * Wp), V, W])
            continue
        segs = [model.stack.segment(n) for n in c.segments]
        us = []
        for k, s in enumerate(segs):
            zeta = (-s.height / 2.0 if k == 0 else s.height / 2.0) if c.kind == "interface" else 0.0
            U, W, Wp = (q_full[model.dof(s.name, f, c.x)] for f in ("U", "W", "W'"))
            us.append([U - zeta * Wp, q_full[model.dof(s.name, "V", c.x)], W])
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


def _write_vtu(path: Path, mesh) -> None:
    import meshio

    write_atomic(path, lambda tmp: meshio.write(tmp, mesh, file_format="vtu"))


def write_series(result, system_or_model_and_T, out_dir, every: int = 10, frame: str = "rotating",
                 prefix: str = "nsfem", phase_deg: float = 0.0) -> Path:
    """Write the VTU series of a run and its ``<prefix>.pvd`` index; returns the .pvd path.

    ``system_or_model_and_T`` is the ContactSystem of :func:`nsfem.simulate.run_scene` or a
    tuple ``(model, T)`` with q_full = T q (e.g. a rebuilt model and the results file's
    ``basis``). Every ``every``-th output time is written (indices 0, every, 2 every, ...).
    ``frame="inertial"`` rotates points and displacements about x by Omega t + phase
    (Omega = 2 pi ``result.info["speed_hz"]``; ``phase_deg`` as ``rotation.phase_deg``, the
    frame in which gravity points along -z).
    """
    import meshio

    if frame not in ("rotating", "inertial"):
        raise NsfemError(f"export: frame must be rotating | inertial, got {frame!r}")
    if not (isinstance(every, int) and every >= 1):
        raise NsfemError(f"export: every must be a positive integer, got {every!r}")
    model, T, contacts = _model_and_T(system_or_model_and_T)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    points, cells, seg_ids, _ = stack_geometry(model)
    # a result computed in the inertial frame is already there: nothing to turn
    turn = frame == "inertial" and result.info.get("frame", "rotating") == "rotating"
    omega = 2.0 * math.pi * float(result.info.get("speed_hz", 0.0)) if turn else 0.0
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
    entries = []
    for i in idx:
        q_full = np.asarray(T @ result.q[:, i]).ravel()
        u = displacements(model, q_full)
        cpos, cdisp = contact_points(model, q_full)
        tf = np.zeros((m, 3))
        for k in range(m):
            for j, vec in enumerate(tangents[k]):
                tf[k] += result.tangential_force[k, j, i] * vec
        p = points
        if frame == "inertial":
            R = rotation(omega * float(result.t[i]) + phase)
            p, u, cpos, cdisp, tf = (a @ R.T for a in (points, u, cpos, cdisp, tf))
        name = f"{prefix}_{i:05d}.vtu"
        _write_vtu(out / name, meshio.Mesh(p, [("hexahedron", cells)], point_data={"displacement": u},
                                           cell_data={"segment": [seg_ids]}))
        cname = f"{prefix}_contacts_{i:05d}.vtu"
        vert = np.arange(m, dtype=np.int64).reshape(-1, 1)
        _write_vtu(out / cname, meshio.Mesh(
            cpos, [("vertex", vert)],
            point_data={"displacement": cdisp, "gap": np.asarray(result.gap[:, i], dtype=float),
                        "normal_force": np.asarray(result.normal_force[:, i], dtype=float),
                        "tangential_force": tf, "state": np.asarray(result.state[:, i], dtype=np.int32)}))
        entries.append((float(result.t[i]), name, cname))
    lines = ['<?xml version="1.0"?>',
             '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">', "  <Collection>"]
    for t, name, cname in entries:
        lines.append(f'    <DataSet timestep="{t!r}" group="" part="0" file={quoteattr(name)}/>')
        lines.append(f'    <DataSet timestep="{t!r}" group="" part="1" file={quoteattr(cname)}/>')
    lines += ["  </Collection>", "</VTKFile>", ""]
    pvd = out / f"{prefix}.pvd"
    write_atomic(pvd, lambda tmp: Path(tmp).write_text("\n".join(lines), encoding="utf-8"))
    return pvd
