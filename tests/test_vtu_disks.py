"""VTU/PVD export of disks and stator rings (nsfem.export.vtu: disk_geometry, stator_geometry, write_series)."""

import math
import xml.etree.ElementTree as ET

import meshio
import numpy as np
import pytest

from nsfem import build_model, load_scene
from nsfem.export.vtu import (DISK_RHO, RING_THICKNESS, RING_WIDTH, SECTORS, disk_displacements, disk_geometry,
                              disk_size, displacements, series_parts, stack_geometry, stator_geometry,
                              write_series)
from nsfem.simulate import run_scene
from nsfem.stack import Disk

from test_vtu import _hex_volumes

EVERY = 10


@pytest.fixture(scope="module")
def rub(tmp_path_factory):
    """The shipped rub (rotating frame, a 5 kg disk given by mass and inertias, a 64-facet ring at its x),
    long enough for the ring to be touched, and its series."""
    scene = load_scene("rub", ["simulation.t_end=0.1", "simulation.output_dt=1e-3"])
    res, system = run_scene(scene, "exact")
    out = tmp_path_factory.mktemp("rub")
    pvd = write_series(res, system, out, every=EVERY)
    model = system.info["model"]
    return scene, res, system, model, np.asarray(system.info["reduction"].T @ res.q), out, pvd


def _parts(pvd):
    """{block name: [(time, file relative to the .pvd's folder), ...]} of a series."""
    return series_parts(pvd)


def test_disk_size_rules():
    # given by mass and polar inertia: the steel cylinder I_p = m R^2 / 2, m = rho pi R^2 w
    D, d, w = disk_size(Disk(0.4, 5.0, polar=0.02, diametral=0.01))
    R = math.sqrt(2 * 0.02 / 5.0)
    assert (D, d) == (pytest.approx(2 * R, rel=1e-15), 0.0)
    assert DISK_RHO * math.pi * (D / 2) ** 2 * w == pytest.approx(5.0, rel=1e-14)
    assert 5.0 * (D / 2) ** 2 / 2 == pytest.approx(0.02, rel=1e-14)
    # a point mass: the steel cylinder as wide as its diameter
    D, d, w = disk_size(Disk(0.4, 5.0))
    assert D == w and DISK_RHO * math.pi * D**2 / 4 * w == pytest.approx(5.0, rel=1e-14)
    # given by its geometry: drawn with it
    assert disk_size(Disk(0.5, 32.6, 0.33, 0.18, outer_diameter=0.28, inner_diameter=0.05, width=0.07)) == \
        (0.28, 0.05, 0.07)


def test_disk_from_mass_drawn_at_x_with_its_radius(rub):
    scene, _, _, model, _, _, _ = rub
    d = model.stack.disks[0]
    pts, cells, ids, owner = disk_geometry(model)
    R = math.sqrt(2 * scene["disk"][0]["polar_inertia"] / scene["disk"][0]["mass"])
    w = scene["disk"][0]["mass"] / (DISK_RHO * math.pi * R**2)
    # the outer vertices lie on the circle of radius R (plus the face centres on the axis), the faces at x +- w/2
    r = np.hypot(pts[:, 1], pts[:, 2])
    assert r.max() == pytest.approx(R, rel=1e-14)
    assert np.all(np.isclose(r, R, rtol=1e-14) | (r == 0.0))
    assert sorted(set(pts[:, 0])) == pytest.approx([d.x - w / 2, d.x + w / 2], rel=1e-15)
    assert d.x == scene["disk"][0]["x"] == pytest.approx(pts[:, 0].mean(), rel=1e-15)
    # a 32-gon times the width, in positive hexahedra (their triple products: 1e-12 as for the shaft's)
    vol = _hex_volumes(pts, cells)
    m = 2 * SECTORS
    assert np.all(vol > 0) and set(ids) == {0} and set(owner) == {0}
    assert vol.sum() == pytest.approx(m / 2 * math.sin(2 * math.pi / m) * R**2 * w, rel=1e-12)


def test_disk_from_geometry_drawn_with_it():
    scene = load_scene("ross_example")
    model = build_model(scene)
    pts, cells, ids, owner = disk_geometry(model)
    assert len(model.stack.disks) == 2 and set(ids) == {0, 1}
    for i, given in enumerate(scene["disk"]):
        p = pts[owner == i]
        r = np.hypot(p[:, 1], p[:, 2])
        # outer and bore vertices only: an annulus
        assert np.all(np.isclose(r, given["outer_diameter"] / 2, rtol=1e-14)
                      | np.isclose(r, given["inner_diameter"] / 2, rtol=1e-14))
        assert sorted(set(p[:, 0])) == pytest.approx([given["x"] - given["width"] / 2, given["x"] + given["width"] / 2],
                                                     rel=1e-15)
        vol = _hex_volumes(pts, cells[ids == i])
        m = 2 * SECTORS
        area = m / 2 * math.sin(2 * math.pi / m) * ((given["outer_diameter"] / 2) ** 2 - (given["inner_diameter"] / 2) ** 2)
        assert np.all(vol > 0) and vol.sum() == pytest.approx(area * given["width"], rel=1e-12)


def test_disk_moves_with_its_node(rub):
    """The disk file's displacement: its points' mean is the node's (U, V, W) (the drawing is symmetric about
    the centre), each point's is the rigid motion u1 = U - eta V' - zeta W', u2 = V + xi V', u3 = W + xi W', and
    the faces differ by the width times the slopes (the tilt)."""
    _, res, _, model, Q, out, pvd = rub
    d = model.stack.disks[0]
    seg = model.stack.carrier(d.x)
    pts, _, _, _ = disk_geometry(model)
    files = _parts(pvd)["disks"]
    assert len(files) == len(range(0, res.t.size, EVERY))
    moved = 0.0
    for k in (3, len(files) - 1):
        i = k * EVERY
        mesh = meshio.read(out / files[k][1])
        np.testing.assert_array_equal(mesh.points, pts)
        u = mesh.point_data["displacement"]
        q = Q[:, i]
        U, V, W, Vp, Wp = (q[model.dof(seg, f, d.x)] for f in ("U", "V", "W", "V'", "W'"))
        # means of 66 terms: a few ulps of the largest displacement (T q per column vs T Q: 1e-13 of it, as in
        # test_vtu)
        scale = np.abs(u).max()
        np.testing.assert_allclose(u.mean(axis=0), [U, V, W], rtol=0, atol=1e-13 * scale)
        xi, eta, zeta = (pts - [d.x, 0.0, 0.0]).T
        want = np.column_stack([U - eta * Vp - zeta * Wp, V + xi * Vp, W + xi * Wp])
        np.testing.assert_allclose(u, want, rtol=0, atol=1e-13 * scale)
        np.testing.assert_allclose(u, disk_displacements(model, q), rtol=0, atol=1e-13 * scale)
        w = disk_size(d)[2]
        front, back = (u[np.isclose(pts[:, 0], d.x + s * w / 2)].mean(axis=0) for s in (1, -1))
        np.testing.assert_allclose((front - back)[1:], [w * Vp, w * Wp], rtol=0, atol=1e-13 * scale)
        assert mesh.cell_data["disk"][0].tolist() == [0] * 16
        moved = max(moved, math.hypot(V, W))
    assert moved > 0.5 * 1e-4    # not vacuous: the disk reaches the ring 0.1 mm away


def test_stator_ring_is_the_models_polygon(rub):
    """The ring's inner corners lie on the circle of radius (clearance + radius) / cos(pi / facets) at the angles
    (2 k + 1) pi / facets, between the facets' normals 2 pi k / facets; each facet's inner face lies at
    clearance + radius along its normal (where the shaft surface touches it at zero gap); the outer corners are
    RING_THICKNESS further out, the ring RING_WIDTH of its inner radius wide at the stator's x."""
    scene, _, _, model, _, _, _ = rub
    st = scene["stator"][0]
    n, rin = st["facets"], st["clearance"] + scene["shaft"]["diameter"] / 2
    pts, cells, ring, contact = stator_geometry(model)
    assert pts.shape == (4 * n, 3) and cells.shape == (n, 8) and set(ring) == {0}
    assert np.all(_hex_volumes(pts, cells) > 0)
    layer = pts[: 2 * n]
    phi = (2 * np.arange(n) + 1) * np.pi / n
    # products and cosines of O(1e-2 m) coordinates: a few ulps (1e-17 m)
    np.testing.assert_allclose(layer[:n, 1:], rin / np.cos(np.pi / n) * np.column_stack([np.cos(phi), np.sin(phi)]),
                               rtol=0, atol=1e-16)
    np.testing.assert_allclose(np.hypot(layer[n:, 1], layer[n:, 2]), (1 + RING_THICKNESS) * rin / np.cos(np.pi / n),
                               rtol=1e-14)
    w = RING_WIDTH * rin
    assert sorted(set(pts[:, 0])) == pytest.approx([st["x"] - w / 2, st["x"] + w / 2], rel=1e-15)
    for k in range(n):
        c = model.stack.contacts[contact[k]]
        normal = np.array([math.cos(c.angle), math.sin(c.angle)])
        assert c.label == f"stator.0.{k}" and c.angle == pytest.approx(2 * math.pi * k / n, rel=1e-15)
        inner = pts[cells[k, [0, 3, 4, 7]]]          # the cell's face towards the shaft
        np.testing.assert_allclose(inner[:, 1:] @ normal, rin, rtol=1e-14)


def test_stator_cell_data_are_the_results(rub):
    """The stator file's per-facet gap, normal force and state are the result's rows of the facets' contacts;
    the tangential force the contacts file's vector; the ring stands still (displacement 0, the same points at
    every time: the rotating-frame run's ring is fixed in that frame, and so is the file)."""
    _, res, _, model, _, out, pvd = rub
    pts, cells, _, contact = stator_geometry(model)
    parts = _parts(pvd)
    loaded = 0
    for k, ((t, sfile), (_, cfile)) in enumerate(zip(parts["stators"], parts["contacts"])):
        i = k * EVERY
        assert t == res.t[i]
        mesh = meshio.read(out / sfile)
        np.testing.assert_array_equal(mesh.points, pts)
        np.testing.assert_array_equal(mesh.cells_dict["hexahedron"], cells)
        assert not mesh.point_data["displacement"].any()
        cd = {name: v[0] for name, v in mesh.cell_data.items()}
        np.testing.assert_array_equal(cd["contact"], contact)
        np.testing.assert_array_equal(cd["gap"], res.gap[contact, i])
        np.testing.assert_array_equal(cd["normal_force"], res.normal_force[contact, i])
        np.testing.assert_array_equal(cd["state"], res.state[contact, i])
        np.testing.assert_array_equal(cd["tangential_force"], meshio.read(out / cfile).point_data["tangential_force"][contact])
        loaded += int((cd["normal_force"] > 0).sum())
    assert loaded   # the ring is touched in some of the files


def test_existing_parts_unchanged_and_parts_named(rub):
    """The .pvd indexes one .vtm a time in vtu/, whose leaf blocks are the parts, named: stack, contacts,
    disks, stators, bearings (rub's damper at the disk), with their files; the stack and contact parts keep their arrays; the index says its frame."""
    _, res, _, model, Q, out, pvd = rub
    root = ET.parse(pvd).getroot()
    ds = list(root.iter("DataSet"))
    taken = range(0, res.t.size, EVERY)
    assert len(ds) == len(taken)
    for d, i in zip(ds, taken):
        assert d.get("file") == f"vtu/nsfem_{i:05d}.vtm" and float(d.get("timestep")) == res.t[i]
        leaves = ET.parse(out / d.get("file")).getroot().iter("DataSet")
        assert [(b.get("index"), b.get("name"), b.get("file")) for b in leaves] == [
            (str(k), name, f.format(i)) for k, (name, f) in enumerate([
                ("stack", "nsfem_{:05d}.vtu"), ("contacts", "nsfem_contacts_{:05d}.vtu"),
                ("disks", "nsfem_disks_{:05d}.vtu"), ("stators", "nsfem_stators_{:05d}.vtu"),
                ("bearings", "nsfem_bearings_{:05d}.vtu")])]
    assert "coordinates in the rotating frame" in pvd.read_text()
    pts, cells, seg, _ = stack_geometry(model)
    i = taken[-1]
    m = meshio.read(out / f"vtu/nsfem_{i:05d}.vtu")
    assert set(m.point_data) == {"displacement"} and set(m.cell_data) == {"segment"}
    np.testing.assert_array_equal(m.points, pts)
    np.testing.assert_array_equal(m.cells_dict["hexahedron"], cells)
    want = displacements(model, Q[:, i])
    np.testing.assert_allclose(m.point_data["displacement"], want, rtol=0, atol=1e-13 * np.abs(want).max())
    c = meshio.read(out / f"vtu/nsfem_contacts_{i:05d}.vtu")
    assert set(c.point_data) == {"displacement", "gap", "normal_force", "tangential_force", "state"}
    np.testing.assert_array_equal(c.point_data["gap"], res.gap[:, i])
    assert not [p for p in out.rglob("*") if p.name.startswith(".") or p.suffix == ".tmp"]


def test_inertial_output_turns_disks_and_rings_with_the_coordinates(rub, tmp_path):
    """A rotating-frame run written in the inertial frame: the disk's points and displacements and the ring
    (fixed in the run's frame) turn by Omega t about x like the stack's."""
    from nsfem.export.vtu import rotation

    _, res, system, model, Q, _, _ = rub
    pvd = write_series(res, system, tmp_path, every=40, frame="inertial")
    assert "inertial frame" in pvd.read_text()
    parts = _parts(pvd)
    dpts, _, _, _ = disk_geometry(model)
    spts, _, _, _ = stator_geometry(model)
    omega = 2 * math.pi * res.info["speed_hz"]
    for k, (t, f) in enumerate(parts["disks"]):
        i = 40 * k
        R = rotation(omega * res.t[i])
        m = meshio.read(tmp_path / f)
        np.testing.assert_allclose(m.points, dpts @ R.T, rtol=0, atol=1e-15)
        u = disk_displacements(model, Q[:, i]) @ R.T
        np.testing.assert_allclose(m.point_data["displacement"], u, rtol=0, atol=1e-13 * np.abs(u).max())
        s = meshio.read(tmp_path / parts["stators"][k][1])
        np.testing.assert_allclose(s.points, spts @ R.T, rtol=0, atol=1e-15)


def test_inertial_run_keeps_its_rings_still(tmp_path):
    """retainer_drop is computed in the inertial frame: its two rings are the same points in every file, and a
    scene without stators or disks writes neither part."""
    res, system = run_scene(load_scene("retainer_drop", ["simulation.t_end=0.01"]))
    pvd = write_series(res, system, tmp_path, every=20, frame="inertial")
    parts = _parts(pvd)
    assert list(parts) == ["stack", "contacts", "disks", "stators", "bearings"]
    first = meshio.read(tmp_path / parts["stators"][0][1])
    assert set(first.cell_data["stator"][0]) == {0, 1}
    for _, f in parts["stators"][1:]:
        np.testing.assert_array_equal(meshio.read(tmp_path / f).points, first.points)
    bare = load_scene(None, ["simulation.t_end=0.002"])
    res, system = run_scene(bare)
    pvd = write_series(res, system, tmp_path / "bare", every=1)
    assert list(_parts(pvd)) == ["stack", "contacts"]


def test_pyvista_reads_every_part(rub):
    pv = pytest.importorskip("pyvista")
    _, _, _, _, _, _, pvd = rub
    reader = pv.get_reader(str(pvd))
    reader.set_active_time_value(reader.time_values[-1])
    (blocks,) = reader.read()   # the time's .vtm
    assert blocks.keys() == ["stack", "contacts", "disks", "stators", "bearings"]
    assert blocks[2].n_cells == 16 and blocks[3].n_cells == 64
    assert "normal_force" in blocks[3].cell_data and "displacement" in blocks[2].point_data


def test_disk_off_centre_tilts_with_the_slopes(tmp_path):
    """A disk away from midspan on a sagging rotor (critical_speed's, moved to x = 0.3): its faces move apart
    along y, z by the width times the slopes (not vacuous: the slope moves the rim by a good part of the
    displacement), and every point follows the rigid motion, in the inertial file as written."""
    res, system = run_scene(load_scene("critical_speed", ["disk.0.x=0.3", "simulation.t_end=0.01"]))
    model = system.info["model"]
    d = model.stack.disks[0]
    pvd = write_series(res, system, tmp_path, every=5)
    k, (t, f) = len(_parts(pvd)["disks"]) - 1, _parts(pvd)["disks"][-1]
    q = np.asarray(system.info["reduction"].T @ res.q[:, 5 * k]).ravel()
    seg = model.stack.carrier(d.x)
    U, V, W, Vp, Wp = (q[model.dof(seg, n, d.x)] for n in ("U", "V", "W", "V'", "W'"))
    D, _, w = disk_size(d)
    assert D / 2 * math.hypot(Vp, Wp) > 0.1 * math.hypot(V, W)
    m = meshio.read(tmp_path / f)
    pts, u = m.points, m.point_data["displacement"]
    xi, eta, zeta = (pts - [d.x, 0.0, 0.0]).T
    scale = np.abs(u).max()
    np.testing.assert_allclose(u, np.column_stack([U - eta * Vp - zeta * Wp, V + xi * Vp, W + xi * Wp]),
                               rtol=0, atol=1e-13 * scale)
    front, back = (u[np.isclose(pts[:, 0], d.x + s * w / 2)].mean(axis=0) for s in (1, -1))
    np.testing.assert_allclose((front - back)[1:], [w * Vp, w * Wp], rtol=0, atol=1e-13 * scale)
