"""nsfem render: an off-screen picture of the deformed stack (pyvista, VTK's EGL window)."""

from __future__ import annotations

import matplotlib.image as mpimg
import numpy as np
import pytest

from nsfem import cli


@pytest.fixture(scope="module")
def saved(tmp_path_factory):
    out = tmp_path_factory.mktemp("render")
    assert cli.main(["run", "--out", str(out), "--set", "simulation.t_end=0.02", "--set", "output.plots=[]",
                     "--set", "output.vtu_every=0"]) == 0
    return out / "result.npz"


def test_render_draws_the_deformed_stack(saved, tmp_path, capsys):
    """The picture exists, is a PNG of the window size, and is not blank: the stack covers a
    good part of it in the colours of its colour maps (more than 3 % of the pixels differ from
    the white background; a blank or failed render has none)."""
    png = tmp_path / "stack.png"
    assert cli.main(["render", str(saved), "--time", "0.01", "--png", str(png), "--exaggeration", "200"]) == 0
    assert str(png) in capsys.readouterr().out
    img = mpimg.imread(png)
    assert img.shape[:2] == (700, 1400)
    drawn = np.any(np.abs(img[:, :, :3] - 1.0) > 0.05, axis=2).mean()
    assert drawn > 0.03
    assert not list(tmp_path.glob(".*.tmp"))


@pytest.mark.parametrize("args, match", [
    (["--time", "5"], "outside the result"),
    (["--exaggeration", "-1"], "exaggeration"),
])
def test_render_rejects_bad_input(saved, args, match, capsys):
    assert cli.main(["render", str(saved), *args]) == cli.EXIT_ERROR
    assert match in capsys.readouterr().err


def test_render_of_a_missing_file(tmp_path, capsys):
    assert cli.main(["render", str(tmp_path / "nope.npz")]) == cli.EXIT_ERROR
    assert "does not exist" in capsys.readouterr().err


# --- issue 34: the parts of the scene in the picture ---
def test_scene_meshes_draw_disk_ring_bearing_and_supports_where_the_model_has_them():
    """rub at rest (q = 0): the disk is the cylinder of disk_size at its x; the ring's inner facets lie at
    surface + scale x clearance from the axis (the clearance drawn at the displacements' scale); the bearing's
    spring stands at its x, below the shaft; the supports' cones at the shaft's ends. The disk's and ring's
    coordinates are sums and products of a few O(1 m) doubles: 1e-12 m is thousands of ulps; pyvista's
    springs, blocks and cones are single precision: 1e-8 m is 100 of their ulps at 1 m."""
    import math

    from nsfem import build_model, load_scene
    from nsfem.export.render import scene_meshes
    from nsfem.export.vtu import disk_size

    model = build_model(load_scene("rub"))
    m = len(model.stack.contacts)
    scale = 400.0
    meshes = scene_meshes(model, np.zeros(model.n_full), np.full(m, 1e-4), scale)
    assert set(meshes) == {"stack", "disks", "stators", "bearings", "supports"}   # no point contacts, no crack
    d = model.stack.disks[0]
    D, _, w = disk_size(d)
    x0, x1, y0, y1, z0, z1 = meshes["disks"].bounds
    assert (x0, x1) == pytest.approx((d.x - w / 2, d.x + w / 2), abs=1e-12)
    assert max(y1 - y0, z1 - z0) == pytest.approx(D, abs=1e-12)
    ring = next(c for c in model.stack.contacts if c.angle is not None)
    facets = sum(c.angle is not None for c in model.stack.contacts)
    pts = meshes["stators"].points
    r = np.hypot(pts[:, 1], pts[:, 2])
    inner = ring.radius + scale * ring.clearance          # 10 mm + 400 x 0.1 mm = 50 mm
    assert r.min() == pytest.approx(inner / math.cos(math.pi / facets), abs=1e-12)
    assert np.allclose(meshes["stators"].cell_data["gap [mm]"], 0.1, rtol=1e-12)
    b = model.stack.bearings[0]
    bx = meshes["bearings"].bounds
    assert bx[0] < b.x < bx[1] and bx[5] <= -ring.radius + 1e-8   # under the shaft at its x
    sx = sorted(s.x for s in model.stack.supports)
    cones = meshes["supports"].bounds
    assert cones[0] < sx[0] and cones[1] > sx[-1] and cones[5] <= -ring.radius + 1e-8


def test_cracks_and_point_contacts_are_drawn():
    """crack: a red collar at the crack's x (no contact spheres for its faces); default: the delamination's
    contact points as spheres, one per contact, and no disk, ring or bearing."""
    from nsfem import build_model, load_scene
    from nsfem.export.render import scene_meshes

    model = build_model(load_scene("crack"))
    meshes = scene_meshes(model, np.zeros(model.n_full), np.zeros(len(model.stack.contacts)), 1.0)
    assert set(meshes) == {"stack", "disks", "supports", "cracks"}
    k = model.stack.cracks[0]
    x0, x1 = meshes["cracks"].bounds[:2]
    assert x0 < k.x < x1 and x1 - x0 < 0.01      # a collar at x, as thick as its tube (3 mm)
    model = build_model(load_scene(None))
    m = len(model.stack.contacts)
    meshes = scene_meshes(model, np.zeros(model.n_full), np.linspace(0, 1e-3, m), 1.0)
    assert set(meshes) == {"stack", "contacts", "supports"}
    assert meshes["contacts"].point_data["gap [mm]"].max() == pytest.approx(1.0, rel=1e-12)
    import pyvista as pv

    assert meshes["contacts"].n_points == m * pv.Sphere().n_points   # one sphere per contact


def test_render_draws_more_than_the_beam(tmp_path):
    """A saved rub run: the picture has an actor per part (stack, disk, ring, bearing, supports), the
    caption names the frame and says the ring's clearance is drawn at the displacements' scale; the PNG
    is written and not blank."""
    from nsfem.export.render import picture
    from nsfem.result import Result

    out = tmp_path / "rub"
    assert cli.main(["run", "rub", "--out", str(out), "--set", "simulation.t_end=0.01", "--set", "output.plots=[]",
                     "--set", "output.vtu_every=0"]) == 0
    res, meta, extra = Result.load(out / "result.npz")
    from nsfem import build_model, load_scene

    model = build_model(load_scene("rub", ["simulation.t_end=0.01"]))
    plotter = picture(res, model, extra["basis"], exaggeration=300.0)
    assert {"stack", "disks", "stators", "bearings", "supports"} <= set(plotter.actors)
    texts = " ".join((a.GetText(2) if a.IsA("vtkCornerAnnotation") else a.GetInput()) or ""
                     for a in plotter.actors.values() if a.IsA("vtkCornerAnnotation") or a.IsA("vtkTextActor"))
    assert "rotating frame" in texts and "ring clearances drawn x 300" in texts
    plotter.close()
    png = tmp_path / "rub.png"
    assert cli.main(["render", str(out / "result.npz"), "--png", str(png)]) == 0
    img = mpimg.imread(png)
    assert np.any(np.abs(img[:, :, :3] - 1.0) > 0.05, axis=2).mean() > 0.03


def test_a_thrust_bearing_is_drawn_along_the_axis():
    """retainer_drop's only bearing is axial (kxx alone, the magnetic bearings failed): its spring runs
    along -x from the shaft's axis at its x (3 shaft depths and the block's 0.3), not down to the ground;
    pyvista's single precision: 1e-6 m at these 0.2 m extents."""
    from nsfem import build_model, load_scene
    from nsfem.export.render import scene_meshes

    model = build_model(load_scene("retainer_drop"))
    (b,) = model.stack.bearings
    assert not np.any(b.K) and not np.any(b.C) and b.kxx > 0
    meshes = scene_meshes(model, np.zeros(model.n_full), np.zeros(len(model.stack.contacts)), 1.0)
    size = max(s.width for s in model.stack.segments)           # the 50 mm round shaft's depth
    x0, x1, _, _, z0, z1 = meshes["bearings"].bounds
    assert x1 == pytest.approx(b.x, abs=1e-6)                    # from the axis point (the tube's ends are open)
    assert x0 == pytest.approx(b.x - 3.3 * size, abs=1e-6)
    assert z1 - z0 == pytest.approx(1.2 * size, abs=1e-6)        # the ground block, upright
