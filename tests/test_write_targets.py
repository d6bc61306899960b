"""Write targets and saved results: every failure is a one-line error (exit 2) naming the path,
checked before the computation where it can be, and nothing is left behind (issue 16).

Each case here ended in a Python traceback, a blank picture or NaN files before.
/proc is a target no process can create files in, not even root (whom os.access lets pass).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

from nsfem import cli

SHORT = ["--set", "simulation.t_end=0.01", "--set", "output.vtu_every=0", "--set", "output.plots=[]",
         "--set", "mesh.elements=20"]
UNWRITABLE = "/proc/nsfem-test"
linux_only = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="needs /proc")


def one_line_error(capsys, code, *needles):
    err = capsys.readouterr().err.strip().splitlines()
    assert code == cli.EXIT_ERROR, err
    assert len(err) == 1 and err[0].startswith("nsfem: error:"), err
    for n in needles:
        assert n in err[0], err
    return err[0]


def tree(path: Path) -> list[str]:
    return sorted(str(p.relative_to(path)) for p in path.rglob("*"))


@pytest.fixture()
def result(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("run")
    assert cli.main(["run", "--out", str(out), *SHORT]) == 0
    return out / "result.npz"


def test_run_out_is_a_file(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    Path("AFILE").write_text("mine")
    one_line_error(capsys, cli.main(["run", "--out", "AFILE", *SHORT]), "AFILE", "is a file")
    assert Path("AFILE").read_text() == "mine"


@pytest.mark.parametrize("inner", ["result.npz", "gap.png"])
def test_run_target_inside_out_is_a_folder(tmp_path, capsys, inner):
    (tmp_path / "D" / inner).mkdir(parents=True)
    code = cli.main(["run", "--out", str(tmp_path / "D"), *SHORT[:-4], "--set", 'output.plots=["gap"]'])
    one_line_error(capsys, code, inner, "is a folder")
    assert tree(tmp_path) == ["D", f"D/{inner}"]


@linux_only
@pytest.mark.parametrize("how", [["--out", UNWRITABLE], ["--set", f"output.dir={UNWRITABLE}"]])
def test_run_out_cannot_be_created(capsys, how):
    one_line_error(capsys, cli.main(["run", *how, *SHORT]), UNWRITABLE)


def test_missing_out_folder_is_created_and_a_refused_run_leaves_none(tmp_path, capsys):
    # the check creates missing folders to try them, and removes them when the run is refused
    target = tmp_path / "a" / "b"
    code = cli.main(["run", "--out", str(target), *SHORT, "--set", "simulation.t_end=-1"])
    assert code == cli.EXIT_ERROR
    assert tree(tmp_path) == []
    assert cli.main(["run", "--out", str(target), *SHORT]) == 0
    assert (target / "result.npz").is_file()


@linux_only
def test_campbell_png_targets(tmp_path, capsys):
    args = ["campbell", "--speeds", "0:30:3", "--set", "mesh.elements=20"]
    one_line_error(capsys, cli.main([*args, "--png", f"{UNWRITABLE}.png"]), "--png")
    (tmp_path / "SOMEDIR").mkdir()
    one_line_error(capsys, cli.main([*args, "--png", str(tmp_path / "SOMEDIR")]), "SOMEDIR", "is a folder")


@linux_only
def test_sweep_out_cannot_be_created(capsys):
    code = cli.main(["sweep", "--out", UNWRITABLE, "--set", "rotation.speed_hz=10:20:2", *SHORT])
    one_line_error(capsys, code, "--out", UNWRITABLE)


@linux_only
def test_export_and_render_targets(result, tmp_path, capsys):
    (tmp_path / "AFILE").write_text("mine")
    one_line_error(capsys, cli.main(["export", str(result), "--vtu", str(tmp_path / "AFILE")]), "is a file")
    one_line_error(capsys, cli.main(["export", str(result), "--vtu", UNWRITABLE]), "--vtu")
    one_line_error(capsys, cli.main(["render", str(result), "--png", f"{UNWRITABLE}.png"]), "--png")
    one_line_error(capsys, cli.main(["render", str(result), "--png", str(tmp_path)]), "is a folder")
    assert tree(tmp_path) == ["AFILE"]


def test_export_of_a_folder_or_a_text_file(result, tmp_path, capsys):
    one_line_error(capsys, cli.main(["export", str(result.parent), "--vtu", str(tmp_path / "x")]), "is a folder")
    text = tmp_path / "notes.txt"
    text.write_text("hello")
    err = one_line_error(capsys, cli.main(["export", str(text), "--vtu", str(tmp_path / "x")]),
                         "not an nsfem results file")
    assert "pickle" not in err
    assert not (tmp_path / "x").exists()


def tampered(result: Path, tmp_path: Path, **change) -> Path:
    with np.load(result) as r:
        arrays = dict(r)
    for k, f in change.items():
        arrays[k] = f(arrays[k])
    path = tmp_path / "tampered.npz"
    np.savez(path, **arrays)
    return path


def test_export_of_a_result_with_a_wrong_basis_leaves_no_folder(result, tmp_path, capsys):
    bad = tampered(result, tmp_path, basis=lambda b: np.eye(3))
    one_line_error(capsys, cli.main(["export", str(bad), "--vtu", str(tmp_path / "vtu")]), "basis is (3, 3)")
    assert not (tmp_path / "vtu").exists()


@pytest.mark.parametrize("command", ["export", "render"])
def test_result_with_nan_displacements_is_refused(result, tmp_path, capsys, command):
    def nan_after_3(q):
        q = q.copy()
        q[:, 3:] = np.nan
        return q

    bad = tampered(result, tmp_path, q=nan_after_3)
    target = ["--vtu", str(tmp_path / "vtu")] if command == "export" else ["--png", str(tmp_path / "r.png")]
    one_line_error(capsys, cli.main([command, str(bad), *target]), "non-finite", "output 3")
    assert tree(tmp_path) == ["tampered.npz"]


@pytest.mark.parametrize("x", ["inf", "nan", "1e300", "-1"])
def test_render_exaggeration_is_bounded(result, tmp_path, capsys, x):
    one_line_error(capsys, cli.main(["render", str(result), "--png", str(tmp_path / "r.png"), "--exaggeration", x]),
                   "--exaggeration")
    assert not (tmp_path / "r.png").exists()


def test_relative_mesh_file_is_found_from_another_folder(tmp_path, monkeypatch, capsys):
    # the scene names its mesh relative to itself; export runs from elsewhere and finds it
    import shutil

    meshes = Path(__file__).resolve().parents[1] / "meshes"
    (tmp_path / "s" / "m").mkdir(parents=True)
    shutil.copy(meshes / "paper_stack_20.msh", tmp_path / "s" / "m" / "stack.msh")
    from nsfem.scene import default_scene_path

    text = default_scene_path().read_text().replace("elements = 40", 'file = "m/stack.msh"')
    assert 'file = "m/stack.msh"' in text
    (tmp_path / "s" / "scene.toml").write_text(text)
    monkeypatch.chdir(tmp_path / "s")
    assert cli.main(["run", "scene.toml", "--out", "out", *SHORT[:-2]]) == 0
    (tmp_path / "elsewhere").mkdir()
    monkeypatch.chdir(tmp_path / "elsewhere")
    capsys.readouterr()
    assert cli.main(["export", "../s/out/result.npz", "--vtu", "vtu"]) == 0
    assert Path("vtu/nsfem.pvd").is_file()
    # a changed mesh is named, not silently used
    (tmp_path / "s" / "m" / "stack.msh").write_bytes(b"changed")
    one_line_error(capsys, cli.main(["export", "../s/out/result.npz", "--vtu", "vtu2"]), "changed since the run")
    assert not Path("vtu2").exists()


def test_title_escape_codes_are_not_echoed_raw(capsys):
    assert cli.main(["modes", "--count", "1", "--set", "mesh.elements=20", "--set",
                     'title="shaft \\u001b[2J\\u001b[31mred"']) == 0
    out = capsys.readouterr().out
    assert "\x1b" not in out and "\\x1b[31m" in out


def test_json_keeps_the_title_as_written(capsys):
    assert cli.main(["modes", "--json", "--count", "1", "--set", "mesh.elements=20", "--set",
                     'title="a\\u001bb"']) == 0
    assert json.loads(capsys.readouterr().out)["title"] == "a\x1bb"


# --- issue 34: the VTU frames in the subfolder vtu/ ---
def test_frames_go_to_vtu_and_the_manifest_lists_them(tmp_path, capsys):
    """A run writes nsfem.pvd beside result.npz and its frames in vtu/, and its manifest names them
    vtu/<name>; the next run without a series removes them and the emptied vtu/, but a user's file
    in vtu/ stays (and so does vtu/)."""
    out = tmp_path / "out"
    assert cli.main(["run", "--out", str(out), *SHORT[:2], "--set", "output.vtu_every=5", *SHORT[4:]]) == 0
    assert sorted(p.name for p in out.iterdir()) == [".nsfem-files.json", "nsfem.pvd", "result.npz", "vtu"]
    listed = json.loads((out / ".nsfem-files.json").read_text())["files"]["series"]
    assert sorted(listed) == sorted(["nsfem.pvd"] + [f"vtu/{p.name}" for p in (out / "vtu").iterdir()])
    assert len(listed) == 1 + 3 * 3    # outputs 0, 5, 10: stack, contacts, .vtm
    assert cli.main(["run", "--out", str(out), *SHORT]) == 0
    assert sorted(p.name for p in out.iterdir()) == [".nsfem-files.json", "result.npz"]
    assert cli.main(["run", "--out", str(out), *SHORT[:2], "--set", "output.vtu_every=5", *SHORT[4:]]) == 0
    (out / "vtu" / "mine.vtu").write_text("mine")
    assert cli.main(["run", "--out", str(out), *SHORT]) == 0
    assert tree(out) == [".nsfem-files.json", "result.npz", "vtu", "vtu/mine.vtu"]


def test_a_file_named_vtu_is_refused_before_the_run(tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    (out / "vtu").write_text("mine")
    code = cli.main(["run", "--out", str(out), *SHORT[:2], "--set", "output.vtu_every=5", *SHORT[4:]])
    one_line_error(capsys, code, "vtu is a file, not a folder")
    assert tree(out) == ["vtu"] and (out / "vtu").read_text() == "mine"
    one_line_error(capsys, cli.main(["export", str(_result_of(tmp_path)), "--vtu", str(out)]), "vtu is a file")


def _result_of(tmp_path: Path) -> Path:
    assert cli.main(["run", "--out", str(tmp_path / "r"), *SHORT]) == 0
    return tmp_path / "r" / "result.npz"


def test_export_frame_of_an_inertial_run(tmp_path, capsys):
    """An inertial-frame run: exported as it is (default) or --frame inertial; --frame rotating is refused in
    one line naming the run's frame, and leaves no folder."""
    run = ["run", "critical_speed", "--out", str(tmp_path / "r"), "--set", "simulation.t_end=0.004",
           "--set", "output.plots=[]", "--set", "output.vtu_every=0"]
    assert cli.main(run) == 0
    result = tmp_path / "r" / "result.npz"
    code = cli.main(["export", str(result), "--vtu", str(tmp_path / "v"), "--frame", "rotating"])
    one_line_error(capsys, code, "--frame", "inertial frame")
    assert not (tmp_path / "v").exists()
    assert cli.main(["export", str(result), "--vtu", str(tmp_path / "v"), "--frame", "inertial"]) == 0
    assert "coordinates in the inertial frame" in (tmp_path / "v" / "nsfem.pvd").read_text()
