"""VTU/PVD export of cracks (nsfem.export.vtu: crack_faces, crack_geometry, crack_displacements, crack_data, and the
crack contacts' points)."""

import math

import meshio
import numpy as np
import pytest

from nsfem import build_model
from nsfem.export.vtu import (CRACK_ARC, contact_points, crack_displacements, crack_faces, crack_geometry, rotation,
                              series_parts, write_series)
from nsfem.fem.crack import SIDE_DIRECTION, ligament_centroid
from nsfem.scene.load import scene_from_tree
from nsfem.simulate import run_scene


def cracked_tree(section="circle", depth=0.4, side="-z", t_end=0.05, x=0.5):
    """A pinned-pinned shaft (a 20 mm circle or a 20 x 12 mm rectangle) with one crack and no other contact,
    rotating at 10 Hz: dropped under gravity from rest, the crack opens and closes within 50 ms."""
    shaft = {"length": 1.0, "section": section, "supports": "pinned-pinned"}
    shaft.update({"diameter": 0.02} if section == "circle" else {"width": 0.02, "height": 0.012})
    return {"title": "cracked", "shaft": shaft, "crack": [{"x": x, "depth": depth, "side": side}],
            "rotation": {"speed_hz": 10.0}, "simulation": {"t_end": t_end}, "mesh": {"elements": 20}}


@pytest.fixture(scope="module")
def cracked(tmp_path_factory):
    """The circular shaft's run (51 output times) and its series, every output time written."""
    res, system = run_scene(scene_from_tree(cracked_tree()))
    out = tmp_path_factory.mktemp("cracked")
    pvd = write_series(res, system, out, every=1)
    model = system.info["model"]
    return res, system, model, np.asarray(system.info["reduction"].T @ res.q), out, pvd


def _parts(pvd):
    """{block name: [(time, file relative to the .pvd's folder), ...]} of a series."""
    return series_parts(pvd)


def _area(yz):
    """Signed (shoelace) area of a polygon (k, 2) in the (y, z) plane: positive when counter-clockwise."""
    y, z = yz.T
    return 0.5 * float(np.sum(y * np.roll(z, -1) - np.roll(y, -1) * z))


@pytest.mark.parametrize("side", ["-z", "+z", "-y", "+y"])
def test_rectangle_face_is_the_cracked_strip(side):
    """A rectangle's face: the strip of depth a = depth x (the side the crack runs along) from the face ``side``,
    across the whole section; its area B a, its corners on the section's outline, its first and last vertices the
    front's ends where the crack's contacts sit (the ligament's centroid a / 2 from the centroid plus their arms)."""
    model = build_model(scene_from_tree(cracked_tree("rectangle", depth=0.3, side=side)))
    (f,) = crack_faces(model)
    dy, dz = SIDE_DIRECTION[side]
    H, B = (0.02, 0.012) if dy else (0.012, 0.02)
    a = 0.3 * H
    face = f["face"]
    assert face.shape == (4, 2) and f["x"] == 0.5 and f["segment"] == "intact_0"
    # products of 1e-2 m lengths: a few ulps of 1e-4 m^2
    assert _area(face) == pytest.approx(B * a, rel=1e-14)
    along = face @ [dy, dz]                      # depth coordinate towards the cracked face
    assert sorted(set(np.round(along, 15))) == pytest.approx([H / 2 - a, H / 2], abs=1e-17)
    np.testing.assert_allclose(np.abs(face @ [-dz, dy]), B / 2, rtol=1e-15)
    np.testing.assert_allclose(f["centre"], -a / 2 * np.array([dy, dz]), rtol=0, atol=1e-18)
    pos, _ = contact_points(model, np.zeros(model.n_full))
    ends = [model.stack.contacts[k] for k in f["contacts"]]
    assert [c.label for c in ends] == ["crack.0.0", "crack.0.1"]
    np.testing.assert_allclose(pos[f["contacts"], 1:], face[[0, -1]], rtol=0, atol=1e-18)
    np.testing.assert_allclose(pos[f["contacts"], 1:], [f["centre"] + c.arm for c in ends], rtol=0, atol=1e-18)
    assert np.all(pos[:, 0] == 0.5)


@pytest.mark.parametrize("depth", [0.1, 0.3, 0.5])
def test_circle_face_is_the_circular_segment(depth):
    """A circle's face: the segment of height a = depth D, its arc drawn as n = CRACK_ARC chords: the polygon's
    area n R^2 sin(2 psi / n) / 2 - R^2 sin psi cos psi exactly, within 1e-3 of the segment's
    R^2 (psi - sin psi cos psi) (cos psi = 1 - a / R; 2.7e-4 to 4.0e-4 here); the arc's vertices on the circle,
    the front's ends the contacts' points."""
    model = build_model(scene_from_tree(cracked_tree("circle", depth=depth, side="-z")))
    (f,) = crack_faces(model)
    R, a = 0.01, depth * 0.02
    psi = math.acos(1 - a / R)
    face = f["face"]
    n = len(face) - 1
    assert n == CRACK_ARC
    segment = R**2 * (psi - math.sin(psi) * math.cos(psi))
    polygon = n * R**2 * math.sin(2 * psi / n) / 2 - R**2 * math.sin(psi) * math.cos(psi)
    assert _area(face) == pytest.approx(polygon, rel=1e-12)
    assert _area(face) == pytest.approx(segment, rel=1e-3)
    np.testing.assert_allclose(np.hypot(*face.T), R, rtol=1e-15)
    assert face[:, 1].max() == pytest.approx(a - R, abs=1e-17)     # on the -z side of the front
    # coordinates of 1e-2 m: an ulp is 1.7e-18 m
    np.testing.assert_allclose(face[[0, -1]], [[-math.sqrt(a * (2 * R - a)), a - R], [math.sqrt(a * (2 * R - a)), a - R]],
                               rtol=0, atol=1e-17)
    assert f["centre"][1] == pytest.approx(-ligament_centroid("circle", 0.02, depth), rel=1e-15)
    pos, _ = contact_points(model, np.zeros(model.n_full))
    np.testing.assert_allclose(pos[f["contacts"], 1:], face[[0, -1]], rtol=0, atol=1e-17)


def test_crack_part_in_the_pvd(cracked):
    """The crack is the third part (no disks, no stators), named ``cracks``, one polygon at every output time
    with the geometry of crack_geometry; pyvista reads it with its cell and point data."""
    res, _, model, _, out, pvd = cracked
    parts = _parts(pvd)
    assert list(parts) == ["stack", "contacts", "cracks"]
    assert [t for t, _ in parts["cracks"]] == res.t.tolist()
    assert parts["cracks"][7][1] == "vtu/nsfem_cracks_00007.vtu"
    pts, polys, owner = crack_geometry(model)
    m = meshio.read(out / parts["cracks"][-1][1])
    np.testing.assert_array_equal(m.points, pts)
    assert [(c.type, c.data.tolist()) for c in m.cells] == [("polygon", [polys[0].tolist()])]
    assert set(m.point_data) == {"displacement", "face_gap"}
    assert set(m.cell_data) == {"crack", "opening", "state", "normal_force"}
    assert set(owner) == {0}
    pv = pytest.importorskip("pyvista")
    reader = pv.get_reader(str(pvd))
    reader.set_active_time_value(reader.time_values[-1])
    block = reader.read()[0]["cracks"]   # the frame's multiblock (its .vtm), its leaves named
    assert block.n_cells == 1 and "state" in block.cell_data and "face_gap" in block.point_data
    assert block.compute_cell_sizes()["Area"][0] == pytest.approx(_area(pts[:, 1:]), rel=1e-12)


def test_crack_state_follows_the_run(cracked):
    """Cell data are the result's: opening the larger gap of the front's two contacts, state how many are closed,
    normal_force their sum; the run has open, partly closed and closed samples, and the file's state says so."""
    res, _, model, _, out, pvd = cracked
    (f,) = crack_faces(model)
    rows = f["contacts"]
    seen = set()
    for i, (t, name) in enumerate(_parts(pvd)["cracks"]):
        cd = {k: v[0] for k, v in meshio.read(out / name).cell_data.items()}
        closed = int((res.state[rows, i] != 0).sum())
        assert cd["crack"].tolist() == [0] and cd["state"].tolist() == [closed]
        assert cd["opening"][0] == res.gap[rows, i].max()
        assert cd["normal_force"][0] == res.normal_force[rows, i].sum()
        if closed == 2:
            assert cd["normal_force"][0] > 0
        seen.add(closed)
    assert seen == {0, 1, 2}
    # (from t = 1 ms: at rest, t = 0, the faces touch, their gap 0 to round-off of either sign)
    open_, shut = (next(i for i in range(1, res.t.size) if (res.state[rows, i] != 0).sum() == k) for k in (0, 2))
    files = _parts(pvd)["cracks"]
    a, b = (meshio.read(out / files[i][1]).cell_data for i in (open_, shut))
    assert (a["state"][0][0], b["state"][0][0]) == (0, 2)
    assert a["opening"][0][0] > 0 and a["normal_force"][0][0] == 0


def test_crack_face_moves_with_the_left_section(cracked):
    """The face's displacement is the left side's section at x, u1 = U - eta V' - zeta W', u2 = V, u3 = W; its
    face_gap at the front's ends is the contacts' gap (the same kinematics: -(arm . (dV', dW'))), and larger
    towards the crack's mouth where the crack is open. The contact points move with the mean of the sides."""
    res, _, model, Q, out, pvd = cracked
    (f,) = crack_faces(model)
    left, right = model.stack.cracks[0].segments
    files = _parts(pvd)["cracks"]
    for i in (10, 30, 50):
        q = Q[:, i]
        m = meshio.read(out / files[i][1])
        u, gap = m.point_data["displacement"], m.point_data["face_gap"]
        U, V, W, Vp, Wp = (q[model.dof(left, n, 0.5)] for n in ("U", "V", "W", "V'", "W'"))
        eta, zeta = m.points[:, 1:].T
        scale = np.abs(u).max()
        want = np.column_stack([U - eta * Vp - zeta * Wp, np.full(eta.size, V), np.full(eta.size, W)])
        np.testing.assert_allclose(u, want, rtol=0, atol=1e-13 * scale)
        np.testing.assert_allclose(u, crack_displacements(model, q)[0], rtol=0, atol=1e-13 * scale)
        # gaps up to 7e-7 m, from the same slopes in another order of operations: ulps of them (measured 2e-22 m)
        np.testing.assert_allclose(gap[[0, -1]], res.gap[f["contacts"], i], rtol=0, atol=1e-20)
        if res.gap[f["contacts"], i].min() > 0:
            assert gap.max() > res.gap[f["contacts"], i].max()
        c = meshio.read(out / f"vtu/nsfem_contacts_{i:05d}.vtu")
        np.testing.assert_allclose(c.points[:, 1:], f["face"][[0, -1]], rtol=0, atol=1e-18)
        sides = []
        for name in (left, right):
            U, V, W, Vp, Wp = (q[model.dof(name, n, 0.5)] for n in ("U", "V", "W", "V'", "W'"))
            sides.append(np.column_stack([U - eta[[0, -1]] * Vp - zeta[[0, -1]] * Wp, [V, V], [W, W]]))
        np.testing.assert_allclose(c.point_data["displacement"], np.mean(sides, axis=0), rtol=0, atol=1e-13 * scale)


def test_inertial_output_turns_the_crack(cracked, tmp_path):
    """Written in the inertial frame, the face and its displacement turn by Omega t about x like the stack."""
    res, system, model, Q, _, _ = cracked
    pvd = write_series(res, system, tmp_path, every=25, frame="inertial")
    pts, _, _ = crack_geometry(model)
    omega = 2 * math.pi * res.info["speed_hz"]
    for k, (t, name) in enumerate(_parts(pvd)["cracks"]):
        R = rotation(omega * res.t[25 * k])
        m = meshio.read(tmp_path / name)
        np.testing.assert_allclose(m.points, pts @ R.T, rtol=0, atol=1e-15)
        u = crack_displacements(model, Q[:, 25 * k])[0] @ R.T
        np.testing.assert_allclose(m.point_data["displacement"], u, rtol=0, atol=1e-13 * max(np.abs(u).max(), 1e-30))
