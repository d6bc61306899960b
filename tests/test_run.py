"""``nsfem run``: the JSON contract, the results file, interruption (design section 5)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from nsfem import cli
from nsfem.integrate import configuration
from nsfem.result import Result

RUN_KEYS = ("method", "t_end", "wall_s", "ndof_full", "ndof", "events", "impacts", "min_gap_m", "max_gap_m",
            "closed_fraction", "max_normal_force_N", "energy", "outputs")
SHORT = ["--set", "mesh.elements=20", "--set", "simulation.t_end=0.05", "--set", "simulation.output_dt=0.005"]


def test_run_json_contract_and_results_file(tmp_path, capsys):
    assert cli.main(["run", "--json", "--out", str(tmp_path), *SHORT]) == 0
    out = json.loads(capsys.readouterr().out)
    for key in RUN_KEYS:
        assert key in out, key
    assert out["method"] == "exact" and out["t_end"] == pytest.approx(0.05) and out["completed"]
    assert out["energy"] < 1e-9  # closed-form propagation: the work balance holds to round-off
    path = tmp_path / "result.npz"
    assert out["outputs"] == [str(path)]
    with np.load(path) as r:  # numpy alone
        meta = json.loads(str(r["meta"]))
        assert r["t"].shape == (11,) and r["gap"].shape == (9, 11)
        assert np.allclose(r["t"], np.linspace(0, 0.05, 11))
        q_full = r["basis"] @ r["q"]
        assert q_full.shape[1] == 11
    assert "delamination" in meta["scene"] and meta["scene_tree"]["simulation"]["t_end"] == 0.05
    res, meta, extra = Result.load(path)
    assert res.summary()["events"] == out["events"] and extra["contact_x"].shape == (9,)


def test_run_rk_agrees_with_exact(tmp_path, capsys):
    gaps = {}
    for method in ("exact", "rk"):
        assert cli.main(["run", "--json", "--method", method, "--out", str(tmp_path / method), *SHORT,
                         "--set", "simulation.rtol=1e-10", "--set", "simulation.atol=1e-14"]) == 0
        json.loads(capsys.readouterr().out)
        with np.load(tmp_path / method / "result.npz") as r:
            gaps[method] = r["gap"]
    # rk at rtol 1e-10 against the closed form: 1e-7 of the largest gap
    assert np.abs(gaps["exact"] - gaps["rk"]).max() <= 1e-7 * np.abs(gaps["exact"]).max()


@pytest.mark.parametrize("args, match", [
    (["--method", "penalty"], "not available"),
    (["--set", "simulation.output_dt=2"], "output_dt"),
    (["--set", "simulation.rtol=2"], "rtol"),
    (["--set", "simulation.rk_solver=LSODA"], "rk_solver"),
])
def test_run_rejects_bad_input_before_computing(args, match, capsys):
    assert cli.main(["run", *args]) == cli.EXIT_ERROR
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and match in err[0]


def test_interrupted_run_leaves_a_valid_results_file(tmp_path, capsys, monkeypatch):
    """Ctrl-C during the integration: the file holds the run up to the last output, exit 130."""
    calls = {"n": 0}
    original = configuration.Phase.xi

    def xi(self, t):
        calls["n"] += 1
        if calls["n"] == 41:  # one Ctrl-C
            raise KeyboardInterrupt
        return original(self, t)

    monkeypatch.setattr(configuration.Phase, "xi", xi)
    code = cli.main(["run", "--json", "--out", str(tmp_path), "--set", "mesh.elements=20",
                     "--set", "simulation.t_end=0.2", "--set", "simulation.output_dt=0.001"])
    assert code == 130
    out = json.loads(capsys.readouterr().out)
    assert out["completed"] is False
    res, meta, _ = Result.load(tmp_path / "result.npz")
    assert not res.completed and 0 < res.t.size < 201
    assert np.all(np.diff(res.t) > 0) and res.gap.shape == (9, res.t.size)
