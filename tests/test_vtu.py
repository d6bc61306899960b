"""VTU/PVD export: geometry, kinematics, gaps and file handling (nsfem.export.vtu)."""

import xml.etree.ElementTree as ET

import meshio
import numpy as np
import pytest

from nsfem import load_scene
from nsfem.export import displacements, stack_geometry, write_series
from nsfem.export.vtu import nodal_dofs, series_parts
from nsfem.simulate import run_scene

EVERY = 10


@pytest.fixture(scope="module")
def run():
    res, sysm = run_scene(load_scene(None, ["simulation.t_end=0.05"]))
    return res, sysm, sysm.info["model"], np.asarray(sysm.info["reduction"].T @ res.q)


@pytest.fixture(scope="module")
def series(run, tmp_path_factory):
    res, sysm, _, _ = run
    out = tmp_path_factory.mktemp("vtu")
    return out, write_series(res, sysm, out, every=EVERY)


def _hex_volumes(points, cells):
    """Volume of hexahedra (VTK ordering) by the divergence theorem over two triangles per face;
    exact for the planar faces of the undeformed stack."""
    faces = [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)]
    vol = np.zeros(len(cells))
    for f in faces:
        a, b, c, d = (points[cells[:, i]] for i in f)
        for p, q, r in ((a, b, c), (a, c, d)):
            vol += np.einsum("ij,ij->i", p, np.cross(q, r)) / 6.0
    return vol


def test_geometry_volumes_and_separate_sub_beams(run):
    _, _, model, _ = run
    pts, cells, seg, book = stack_geometry(model)
    assert pts.shape == book.shape and cells.shape[1] == 8
    vol = _hex_volumes(pts, cells)
    assert np.all(vol > 0)
    # the 12 triple products of a cell sum to at most 30x its volume (x up to 1 m against a 2 cm
    # section): <= 12 eps x 30 = 8e-14 of each cell (measured 2.2e-16 per segment)
    for i, s in enumerate(model.stack.segments):
        assert vol[seg == i].sum() == pytest.approx(s.width * s.height * s.length, rel=1e-12)
    # a delamination's sub-beams share no point, and the upper's bottom face is the lower's top face:
    # offset + half height, operands <= 5.5 mm, ulp 8.7e-19 (measured 0)
    up, lo = (k for k, s in enumerate(model.stack.segments) if s.name.startswith("delamination_0_"))
    zu, zl = pts[book[:, 0] == up, 2], pts[book[:, 0] == lo, 2]
    assert zu.min() == pytest.approx(zl.max(), abs=1e-17)
    # the same check with pyvista's cell sizes
    pv = pytest.importorskip("pyvista")
    grid = pv.UnstructuredGrid({pv.CellType.HEXAHEDRON: cells}, pts)
    sizes = grid.compute_cell_sizes(length=False, area=False, volume=True).cell_data["Volume"]
    # VTK's own decomposition cancels alike: 8e-14 per cell (measured 6.2e-15)
    assert np.allclose(sizes, vol, rtol=1e-12, atol=0)


def test_displacement_kinematics(run):
    res, _, model, Q = run
    q = Q[:, -1]
    u = displacements(model, q)
    pts, _, _, book = stack_geometry(model)
    assert u.shape == pts.shape
    s = model.stack.segments[1]
    d = nodal_dofs(model, s.name)
    node = 5
    x = model.spaces[s.name].x[node]
    for corner in range(4):
        p = np.flatnonzero((book[:, 0] == 1) & (book[:, 1] == node) & (book[:, 2] == corner))[0]
        eta, zeta = pts[p, 1] - s.offset[0], pts[p, 2] - s.offset[1]
        want = [q[model.dof(s.name, "U", x)] - eta * q[model.dof(s.name, "V'", x)]
                - zeta * q[model.dof(s.name, "W'", x)], q[model.dof(s.name, "V", x)], q[model.dof(s.name, "W", x)]]
        # the same three-term formula: at most a few roundings of terms <= max|u| (measured exact)
        assert np.allclose(u[p], want, rtol=0, atol=1e-15 * np.abs(u).max())
        assert q[d["W"][node]] == q[model.dof(s.name, "W", x)]


def test_series_files_meshio_vtk_and_pvd(run, series):
    res, _, model, Q = run
    out, pvd = series
    assert pvd.name == "nsfem.pvd" and pvd.is_file()
    assert not [p for p in out.rglob("*") if p.name.startswith(".") or p.suffix == ".tmp"]
    root = ET.parse(pvd).getroot()
    assert root.get("type") == "Collection"
    parts = series_parts(pvd)
    taken = np.arange(0, res.t.size, EVERY)
    for part in ("stack", "contacts"):
        t = np.array([t for t, _ in parts[part]])
        assert np.all(np.diff(t) > 0) and np.array_equal(t, res.t[taken])
    files = [f for _, f in parts["stack"]]
    pts, cells, seg, _ = stack_geometry(model)
    from vtkmodules.util.numpy_support import vtk_to_numpy
    from vtkmodules.vtkIOXML import vtkXMLUnstructuredGridReader

    for i, f in zip(taken, files):
        m = meshio.read(out / f)
        assert m.points.shape == pts.shape and m.point_data["displacement"].shape == (len(pts), 3)
        assert np.array_equal(m.cells_dict["hexahedron"], cells)
        assert np.array_equal(m.cell_data["segment"][0], seg)
        # T q per column (gemv) vs T Q (gemm): sums of 25 products in another order, <= 25 eps |T| |q|
        # = 25 x 2.2e-16 x 10.8 |T q| = 6e-14 of the largest (measured <= 6.4e-16 over four kernels)
        want = displacements(model, Q[:, i])
        assert np.allclose(m.point_data["displacement"], want, rtol=0, atol=1e-13 * np.abs(want).max())
        r = vtkXMLUnstructuredGridReader()
        r.SetFileName(str(out / f))
        r.Update()
        g = r.GetOutput()
        assert g.GetNumberOfPoints() == len(pts) and g.GetNumberOfCells() == len(cells)
        assert vtk_to_numpy(g.GetPointData().GetArray("displacement")).shape == (len(pts), 3)
    cfiles = [f for _, f in parts["contacts"]]
    for i, f in zip(taken, cfiles):
        c = meshio.read(out / f)
        assert c.points.shape == (res.gap.shape[0], 3)
        assert np.array_equal(c.point_data["gap"], res.gap[:, i])
        assert np.array_equal(c.point_data["normal_force"], res.normal_force[:, i])
        assert c.point_data["tangential_force"].shape == (res.gap.shape[0], 3)
        assert np.array_equal(c.point_data["state"], res.state[:, i])


def test_gap_seen_in_vtu_equals_result_gap(run, series):
    res, _, model, Q = run
    out, pvd = series
    _, _, _, book = stack_geometry(model)
    names = [s.name for s in model.stack.segments]
    worst = 0.0
    for k_out, (_, f) in enumerate(series_parts(pvd)["stack"]):
        i = k_out * EVERY
        m = meshio.read(out / f)
        cur = m.points + m.point_data["displacement"]
        for k, c in enumerate(model.stack.contacts):
            up, lo = (names.index(n) for n in c.segments)
            nu = model.spaces[c.segments[0]].node(c.x)
            nl = model.spaces[c.segments[1]].node(c.x)
            bottom = cur[(book[:, 0] == up) & (book[:, 1] == nu) & np.isin(book[:, 2], (0, 1)), 2]
            top = cur[(book[:, 0] == lo) & (book[:, 1] == nl) & np.isin(book[:, 2], (2, 3)), 2]
            gap = bottom.mean() - top.mean()
            worst = max(worst, abs(gap - res.gap[k, i]))
    # the gaps are reduced coordinates (C V = [I 0] to ~1e-13, test_reduce) against face heights from
    # T q (6e-14 of max|T q|, above) added to 5 mm coordinates (ulp 8.7e-19): ~1e-13 max|T q|
    # (measured 4.3e-19 m = 1e-16 of it)
    assert worst < 1e-12 * np.abs(Q).max()
    assert np.abs(res.gap).max() > 1e-7  # the check is not vacuous: the interface does open


def test_inertial_frame_rotates_about_x(run, tmp_path):
    res, sysm, model, Q = run
    pvd = write_series(res, sysm, tmp_path, every=25, frame="inertial", prefix="iner")
    pts, _, _, _ = stack_geometry(model)
    omega = 2 * np.pi * res.info["speed_hz"]
    for k, (_, f) in enumerate(series_parts(pvd)["stack"]):
        i = 25 * k
        m = meshio.read(tmp_path / f)
        a = omega * res.t[i]
        R = np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])
        # the same product with the same angle (numpy's and math's cos, sin may differ by an ulp): a few
        # ulps of the 1 m coordinates (measured exact)
        assert np.allclose(m.points, pts @ R.T, rtol=0, atol=1e-15)
        # displacements from T q vs T Q, as in test_series_files_meshio_vtk_and_pvd (measured 3.3e-19 m)
        u = displacements(model, Q[:, i]) @ R.T
        assert np.allclose(m.point_data["displacement"], u, rtol=0, atol=1e-13 * np.abs(u).max())
    assert not [p for p in tmp_path.rglob("*") if p.name.startswith(".")]


def test_model_and_T_tuple_and_bad_args(run, tmp_path):
    res, sysm, model, _ = run
    pvd = write_series(res, (model, sysm.info["reduction"].T), tmp_path, every=50)
    assert len([d for d in ET.parse(pvd).getroot().iter("DataSet")]) == len(range(0, res.t.size, 50))
    assert [len(v) for v in series_parts(pvd).values()] == [len(range(0, res.t.size, 50))] * 2
    with pytest.raises(Exception, match="frame"):
        write_series(res, sysm, tmp_path, frame="lab")


def test_stator_friction_force_is_drawn_along_the_circumference(tmp_path):
    """A frictional rub's contact file: each closed facet's tangential force is mu N along its circumferential
    tangent t = (0, -sin a, cos a), opposing the surface's motion (a vector, not a component per axis)."""
    import math

    import meshio

    from nsfem import load_scene
    from nsfem.export.vtu import write_series
    from nsfem.simulate import run_scene

    scene = load_scene("rub", ["simulation.t_end=0.3", "simulation.output_dt=1e-2"])
    res, system = run_scene(scene, "exact")
    write_series(res, system, tmp_path, every=30)
    mesh = meshio.read(tmp_path / "vtu" / "nsfem_contacts_00030.vtu")
    tf = mesh.point_data["tangential_force"]
    mu, facets = scene["stator"][0]["friction"], scene["stator"][0]["facets"]
    # each facet's point sits on the shaft surface it faces (radius 10 mm along its normal), and the ring's
    # clearance less the normal part of that point's displacement is the result's gap (to the round-off
    # of 1e-4 m clearances: 1e-12 of it)
    a = 2 * math.pi * np.arange(facets) / facets
    R = scene["shaft"]["diameter"] / 2
    np.testing.assert_allclose(mesh.points[:, 1:], R * np.column_stack([np.cos(a), np.sin(a)]), atol=1e-15)
    u = mesh.point_data["displacement"]
    g = scene["stator"][0]["clearance"] - (np.cos(a) * u[:, 1] + np.sin(a) * u[:, 2])
    np.testing.assert_allclose(g, res.gap[:, 30], rtol=0, atol=1e-12 * scene["stator"][0]["clearance"])
    # re-exported from the model and the basis alone (`nsfem export --vtu`: no contact set), the same forces
    # (raised KeyError 'stator' before)
    write_series(res, (system.info["model"], system.info["reduction"].T), tmp_path / "again", every=30)
    again = meshio.read(tmp_path / "again" / "vtu" / "nsfem_contacts_00030.vtu")
    np.testing.assert_array_equal(again.point_data["tangential_force"], tf)
    closed = np.flatnonzero(res.normal_force[:, 30] > 0)
    assert closed.size
    # the file's vector is mu N t formed from the same floats (a few roundings of each component: 1e-12)
    for k in closed:
        a = 2 * math.pi * k / facets
        np.testing.assert_allclose(tf[k], -mu * res.normal_force[k, 30] * np.array([0.0, -math.sin(a), math.cos(a)]),
                                   rtol=1e-12, atol=1e-12 * res.normal_force[k, 30])


@pytest.mark.parametrize("inner", [0.0, 0.012])
def test_round_shafts_are_drawn_round(inner, tmp_path):
    """A circular section is a 32-gon tiled by quadrilaterals (from its centre, or between its bore and its
    surface): every hexahedron has a positive volume, they add up to the polygons' areas times the length
    (to 1e-12: the cells' triple products, as for the rectangles), and the surface points lie on the
    circle, displaced by the beam kinematics u1 = U - eta V' - zeta W'."""
    import math

    from nsfem.export.vtu import SECTORS

    scene = load_scene("rub", [f"shaft.inner_diameter={inner}", "simulation.t_end=0.01"])
    res, system = run_scene(scene)
    model = system.info["model"]
    pts, cells, seg, book = stack_geometry(model)
    vol = _hex_volumes(pts, cells)
    assert np.all(vol > 0)
    D, L, m = scene["shaft"]["diameter"], scene["shaft"]["length"], 2 * SECTORS
    polygon = m / 2 * math.sin(2 * math.pi / m) * ((D / 2) ** 2 - (inner / 2) ** 2)
    assert vol.sum() == pytest.approx(polygon * L, rel=1e-12)
    r = np.hypot(pts[:, 1], pts[:, 2])
    assert np.all(np.isclose(r, D / 2, rtol=1e-14) | np.isclose(r, inner / 2, rtol=1e-14, atol=1e-18))
    q = np.asarray(system.info["reduction"].T @ res.q[:, -1]).ravel()
    u = displacements(model, q)
    s = model.stack.segments[0]
    node = 7
    x = model.spaces[s.name].x[node]
    for p in np.flatnonzero((book[:, 1] == node))[:5]:
        eta, zeta = pts[p, 1], pts[p, 2]
        want = [q[model.dof(s.name, "U", x)] - eta * q[model.dof(s.name, "V'", x)] - zeta * q[model.dof(s.name, "W'", x)],
                q[model.dof(s.name, "V", x)], q[model.dof(s.name, "W", x)]]
        assert np.allclose(u[p], want, rtol=0, atol=1e-15 * np.abs(u).max())
    write_series(res, system, tmp_path, every=5)     # and the files take the new cells
    mesh = meshio.read(tmp_path / "vtu" / "nsfem_00000.vtu")
    assert mesh.cells[0].data.shape == cells.shape


# --- issue 34: the series in a subfolder, named leaves, the inertial frame from the command line ---
def test_pvd_indexes_vtm_frames_in_the_subfolder_with_named_leaves(run, series):
    """The .pvd at the top indexes one .vtm a time in vtu/ by a relative path; every file it and the .vtm
    name exists in vtu/; VTK's multiblock reader gives the leaves their names (stack, contacts)."""
    import vtk
    from vtkmodules.vtkIOXML import vtkXMLMultiBlockDataReader

    res, _, _, _ = run
    out, pvd = series
    assert sorted(p.name for p in out.iterdir()) == ["nsfem.pvd", "vtu"]
    files = [d.get("file") for d in ET.parse(pvd).getroot().iter("DataSet")]
    assert files == [f"vtu/nsfem_{i:05d}.vtm" for i in range(0, res.t.size, EVERY)]
    named = {f for v in series_parts(pvd).values() for _, f in v}
    assert {str(p.relative_to(out)) for p in (out / "vtu").iterdir()} == set(files) | named
    r = vtkXMLMultiBlockDataReader()
    r.SetFileName(str(out / files[-1]))
    r.Update()
    mb = r.GetOutput()
    names = [mb.GetMetaData(i).Get(vtk.vtkCompositeDataSet.NAME()) for i in range(mb.GetNumberOfBlocks())]
    assert names == ["stack", "contacts"]
    assert mb.GetBlock(1).GetNumberOfPoints() == res.gap.shape[0]


def test_no_contacts_block_without_contacts_and_the_bearings_block(tmp_path):
    """critical_speed has no contacts: its frames are the stack, the disk and the bearings, no empty contacts
    block. The bearings block: a vertex on the axis at each bearing's x with the scene's stiffness and
    damping (as given: exact) and the shaft's displacement there (the same dofs of T q: exact)."""
    scene = load_scene("critical_speed", ["simulation.t_end=0.005"])
    res, system = run_scene(scene)
    pvd = write_series(res, system, tmp_path, every=5)
    parts = series_parts(pvd)
    assert list(parts) == ["stack", "disks", "bearings"]
    assert not list((tmp_path / "vtu").glob("*contacts*"))
    model = system.info["model"]
    m = meshio.read(tmp_path / parts["bearings"][-1][1])
    i = 5 * (len(parts["bearings"]) - 1)
    q = np.asarray(system.info["reduction"].T @ res.q[:, i]).ravel()
    for k, (b, want) in enumerate(zip(model.stack.bearings, scene["bearing"])):
        assert m.points[k].tolist() == [b.x, 0.0, 0.0]
        assert m.point_data["stiffness"][k].tolist() == [want["kyy"], want["kzz"], want["kyz"], want["kzy"]]
        assert m.point_data["damping"][k].tolist() == [want["cyy"], want["czz"], want["cyz"], want["czy"]]
        seg = model.stack.carrier(b.x)
        assert m.point_data["displacement"][k].tolist() == [q[model.dof(seg, f, b.x)] for f in ("U", "V", "W")]
    assert np.abs(m.point_data["displacement"]).max() > 0   # not vacuous: the shaft sags at the bearings


def test_export_inertial_equals_the_python_path(tmp_path, capsys):
    """`nsfem export RESULT --vtu DIR --frame inertial` of a rotating-frame run (phase 30 deg) writes what
    write_series(frame="inertial") writes from the run itself: the same points and displacements (the
    results file's dense basis against the run's T: T q in another order of sums, 1e-13 of the largest
    displacement as in test_series_files_meshio_vtk_and_pvd; the coordinates ulps of 1 m)."""
    from nsfem import cli

    sets = ["simulation.t_end=0.02", "rotation.phase_deg=30"]
    res, system = run_scene(load_scene(None, sets))
    pvd = write_series(res, system, tmp_path / "py", every=5, frame="inertial")
    argv = [a for s in sets for a in ("--set", s)]
    assert cli.main(["run", "--out", str(tmp_path / "run"), *argv, "--set", "output.plots=[]",
                     "--set", "output.vtu_every=0"]) == 0
    assert cli.main(["export", str(tmp_path / "run" / "result.npz"), "--vtu", str(tmp_path / "cli"), "--every", "5",
                     "--frame", "inertial"]) == 0
    assert "inertial frame" in capsys.readouterr().out
    cli_pvd = tmp_path / "cli" / "nsfem.pvd"
    assert "coordinates in the inertial frame" in cli_pvd.read_text()
    py, cl = series_parts(pvd), series_parts(cli_pvd)
    assert py == cl and list(py) == ["stack", "contacts"]
    for frames in py.values():
        for _, f in frames:
            a, b = meshio.read(tmp_path / "py" / f), meshio.read(tmp_path / "cli" / f)
            np.testing.assert_allclose(b.points, a.points, rtol=0, atol=1e-15)
            u = a.point_data["displacement"]
            np.testing.assert_allclose(b.point_data["displacement"], u, rtol=0, atol=1e-13 * np.abs(u).max())
    # not vacuous: at t = 0 the points are already turned by the phase (30 deg of 20 mm sections: ~5 mm)
    rest = stack_geometry(system.info["model"])[0]
    first = meshio.read(tmp_path / "cli" / py["stack"][0][1]).points
    assert np.abs(first[:, 1:] - rest[:, 1:]).max() > 1e-3


# --- issue 34: latency, second pass (a series looks each dof up once) ---------------------------------------
def test_a_series_looks_each_dof_up_once_and_writes_what_a_fresh_look_up_gives(run, tmp_path, monkeypatch):
    """write_series caches model.dof: a series of every output time (6 frames) asks the model exactly the
    look-ups one frame asks, each once; its contact points are those contact_points computes without the cache
    (the same indices into the same vector, T q formed as write_series forms it: bitwise)."""
    from nsfem.export.vtu import contact_points

    res, sysm, model, _ = run
    calls = []
    real = model.dof
    monkeypatch.setattr(model, "dof", lambda *a: (calls.append(a), real(*a))[1])
    write_series(res, sysm, tmp_path / "one", every=res.t.size)
    one = list(calls)
    calls.clear()
    pvd = write_series(res, sysm, tmp_path / "all", every=EVERY)
    assert one and len(set(one)) == len(one) and sorted(calls) == sorted(one)
    monkeypatch.setattr(model, "dof", real)
    (t, last), *_ = reversed(series_parts(pvd)["contacts"])
    i = int(np.argmin(np.abs(res.t - t)))
    pos, disp = contact_points(model, np.asarray(sysm.info["reduction"].T @ res.q[:, i]).ravel())
    frame = meshio.read(pvd.parent / last)
    assert i > 0 and np.array_equal(frame.points, pos) and np.array_equal(frame.point_data["displacement"], disp)
