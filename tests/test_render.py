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
