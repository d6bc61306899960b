"""Parameter sweeps (``nsfem sweep``): the same numbers as single runs, failures in their rows,
resumption, one model per sweep of the speed, and the command line's errors."""

from __future__ import annotations

import csv
import importlib
import json

import numpy as np
import pytest

import nsfem
from nsfem import cli
from nsfem.errors import NsfemError
from nsfem.result import Result
from nsfem.simulate import run_scene
from nsfem.sweep import RUN_KEYS, parse_ranges, run_sweep

ASSEMBLE = importlib.import_module("nsfem.fem.assemble")  # the module, not the function
REDUCE = importlib.import_module("nsfem.reduce")
BASE = ["mesh.elements=20", "simulation.t_end=0.04"]


@pytest.fixture(scope="module")
def client():
    """One 2-process LocalCluster for the module (starting one takes a few seconds)."""
    distributed = pytest.importorskip("distributed")
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0",
                                       silence_logs=50)
    c = distributed.Client(cluster)
    yield c
    c.close()
    cluster.close()


@pytest.fixture
def inprocess():
    """A one-thread in-process cluster: monkeypatches reach the runs."""
    distributed = pytest.importorskip("distributed")
    c = distributed.Client(processes=False, n_workers=1, threads_per_worker=1, dashboard_address=":0")
    yield c
    c.close()


def _assert_same_run(got, ref, names):
    """The same run: times and contact states exactly; the float arrays to the round-off of BLAS.

    Workers run BLAS single-threaded; this process may not, and a threaded BLAS sums in another
    order (measured: 1e-17 of the largest value, the same events). Bit for bit needs equal thread
    counts; 1e-12 of the largest value is round-off (another summation order changes the reduced
    operators, dense products over the 200 full dofs, by at most n eps = 4.4e-14, and a 0.04 s
    window of linear flights moves the histories in proportion), while a change of physics moves
    them by far more (friction 0 against 0.3 below: the gaps differ by 1e-3 of the largest gap)."""
    for name in names:
        a, b = getattr(got, name), getattr(ref, name)
        assert a.shape == b.shape, name
        if name in ("t", "state"):
            assert np.array_equal(a, b), name
        else:
            scale = np.abs(b).max() if b.size else 0.0
            assert np.allclose(a, b, rtol=0.0, atol=1e-12 * scale), name


def test_sweep_equals_single_runs(client, tmp_path):
    lines = []
    res = run_sweep(None, BASE + ["rotation.speed_hz=15:25:3"], tmp_path, client=client, progress=lines.append)
    assert [p["rotation.speed_hz"] for p in res.points] == [15, 20, 25]
    assert res.info["executed"] == 3 and res.info["models_built"] == 1 and not res.failed
    assert lines[0] == f"3 runs to do (rotation.speed_hz: 3 values) into {tmp_path}"  # the plan first
    assert len(lines) == 4 and all(line.startswith("[") and "rotation.speed_hz=" in line for line in lines[1:])
    for point, row in zip(res.points, res.runs):
        scene = nsfem.load_scene(None, BASE + [f"rotation.speed_hz={point['rotation.speed_hz']}"])
        ref, _ = run_scene(scene)
        want = ref.summary()
        for key in RUN_KEYS:
            if key != "wall_s":
                assert row[key] == want[key], key
        got, _, _ = Result.load(row["result"])
        _assert_same_run(got, ref, ("t", "q", "v", "gap", "normal_force", "state"))
    assert res.runs[0]["events"] > 0  # 15 Hz touches within the window: the comparison is not trivial
    with open(res.table) as fh:
        rows = list(csv.DictReader(fh))
    assert [float(r["rotation.speed_hz"]) for r in rows] == [15, 20, 25]
    assert all(r["error"] == "" and r["result"].endswith("result.npz") for r in rows)
    assert res.figure is not None and res.figure.stat().st_size > 0
    payload = json.loads((tmp_path / "sweep.json").read_text())
    assert payload["parameter"] == "rotation.speed_hz" and payload["values"] == [15, 20, 25]
    assert len(payload["runs"]) == 3


def test_failing_run_is_reported_in_its_row_and_retried_on_resume(client, tmp_path):
    # beyond the divergence speeds the stationary state (LCP 28) has no solution Lemke can reach:
    # a genuine failure of the 90 Hz run only, after every value validated
    args = BASE + ["initial.state=stationary", "rotation.speed_hz=20:90:2"]
    res = run_sweep(None, args, tmp_path, client=client)
    ok, bad = res.runs
    assert ok["error"] == "" and ok["completed"] is True
    assert "stationary LCP" in bad["error"] and bad["result"] == "" and bad["closed_fraction"] is None
    assert len(res.failed) == 1
    with open(res.table) as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 2 and rows[1]["error"] and not rows[0]["error"]
    again = run_sweep(None, args, tmp_path, client=client)
    assert again.info["resumed"] == 1 and again.info["executed"] == 1  # only the failed one runs again


def test_resume_skips_finished_runs(client, tmp_path):
    args = BASE + ["rotation.speed_hz=15:25:3"]
    first = run_sweep(None, args, tmp_path, client=client)
    again = run_sweep(None, args, tmp_path, client=client)
    assert again.info["executed"] == 0 and again.info["resumed"] == 3
    assert [r["result"] for r in again.runs] == [r["result"] for r in first.runs]
    more = run_sweep(None, BASE + ["rotation.speed_hz=15:30:4"], tmp_path, client=client)  # adds 30 Hz
    assert more.info["executed"] == 1 and more.info["resumed"] == 3
    (tmp_path / "rotation.speed_hz=20" / "record.json").unlink()  # as if that run had been cut short
    assert run_sweep(None, args, tmp_path, client=client).info["executed"] == 1
    # another scene setting in the same folder would mix results: refused before anything runs
    with pytest.raises(NsfemError, match="holds another sweep"):
        run_sweep(None, args + ["rotation.gravity=5.0"], tmp_path, client=client)


def test_speed_sweep_builds_one_model(inprocess, tmp_path, monkeypatch):
    calls = {"build_model": 0, "scene_reduction": 0}

    def counting(name, fn):
        def wrapper(*a, **k):
            calls[name] += 1
            return fn(*a, **k)
        return wrapper

    monkeypatch.setattr(ASSEMBLE, "build_model", counting("build_model", ASSEMBLE.build_model))
    monkeypatch.setattr(REDUCE, "scene_reduction", counting("scene_reduction", REDUCE.scene_reduction))
    args = ["simulation.t_end=0.02", "initial.state=stationary", "damping.external=0.1"]
    res = run_sweep(None, args + ["mesh.elements=20", "rotation.speed_hz=10:30:3"], tmp_path / "a",
                    client=inprocess, plot=False)
    assert not res.failed and res.info["executed"] == 3
    assert calls == {"build_model": 1, "scene_reduction": 1} and res.info["models_built"] == 1
    # a grid over speed and mesh: one model per mesh, shared by that mesh's speeds
    res = run_sweep(None, args + ["rotation.speed_hz=10:30:2", "mesh.elements=20:24:2"], tmp_path / "b",
                    client=inprocess, plot=False)
    assert not res.failed and res.info["models_built"] == 2
    assert calls == {"build_model": 3, "scene_reduction": 3}
    payload = res.to_json()
    assert payload["parameter"] == ["rotation.speed_hz", "mesh.elements"]
    assert payload["values"] == [[10, 20], [10, 24], [30, 20], [30, 24]]
    assert [r["ndof_full"] for r in res.runs][:2] == [175, 215]


def test_cli_sweep_reports_failures_with_exit_2(tmp_path, capsys):
    argv = ["sweep", "--set", "mesh.elements=20", "--set", "simulation.t_end=0.02", "--set",
            "initial.state=stationary", "--set", "rotation.speed_hz=20:90:2", "--workers", "1",
            "--out", str(tmp_path), "--json"]
    assert cli.main(argv) == cli.EXIT_ERROR
    out, err = capsys.readouterr()
    payload = json.loads(out)
    assert out.count("\n") == 1 and payload["values"] == [20, 90] and payload["failed"] == 1
    assert payload["runs"][0]["error"] == "" and payload["runs"][1]["error"]
    lines = err.strip().splitlines()
    assert lines[0].startswith("2 runs to do (rotation.speed_hz: 2 values) into ")
    assert lines[1].startswith("[1/2]") and lines[2].startswith("[2/2]")
    assert lines[-1].startswith("nsfem: error: 1 of 2 runs failed") and len(lines) == 4


@pytest.mark.parametrize("argv, words", [
    (["--set", "rotation.speed_hz=10:20"], "START:STOP:N"),
    (["--set", "rotation.speed_hz=10:20:0"], "N must be a positive integer, got '0'"),
    (["--set", "rotation.speed_hz=10:20:x"],
     "--set rotation.speed_hz=START:STOP:N: N must be a positive integer, got 'x'"),
    (["--set", "rotation.speed_hz=10:20:1"], "N = 1 needs START = STOP"),
    (["--set", "rotation.speed_hz=nan:20:3"], "START must be a finite number, got 'nan'"),
    (["--set", "rotation.speed_hz=10:inf:3"], "STOP must be a finite number, got 'inf'"),
    (["--set", "rotation.speed_hz=10:20:10001"], "N = 10001 exceeds the limit of 10000"),
    (["--set", "rotation.speed_hz=10:20:1000", "--set", "damping.external=0:1:1000"], "more than the limit"),
    (["--set", "rotation.speed_hz=10:20:3", "--workers", "2", "--scheduler", "tcp://127.0.0.1:1"], "--scheduler"),
    (["--set", "rotation.speed_hz=10:20:3", "--workers", "0"], "positive"),
    (["--set", "rotation.speed_hz=10:20:3", "--scheduler", "nonsense"], "--scheduler nonsense: cannot connect"),
    (["--set", "rotation.sped_hz=10:20:3"], "rotation.sped_hz: unknown key"),
    (["--set", "rotation.speed_hz=-10:20:3"], "rotation.speed_hz: must be >= 0"),
    (["--set", "rotation.speed_hz=10:20:3", "--set", "rotation.speed_hz=5"], "both swept and fixed"),
    (["--set", "mesh.elements=5:25:3"], "mesh.elements"),
    ([], "nothing to sweep"),
], ids=["two-parts", "n-zero", "n-not-a-number", "n-one-two-ends", "nan", "inf", "too-many", "grid-too-many",
        "workers-and-scheduler", "workers-zero", "bad-scheduler", "unknown-key",
        "bad-value", "swept-and-fixed", "bad-value-in-range", "no-range"])
def test_cli_sweep_errors_are_one_line(argv, words, capsys, tmp_path, monkeypatch):
    monkeypatch.setattr(ASSEMBLE, "build_model", lambda *a: pytest.fail("built a model for a bad sweep"))
    assert cli.main(["sweep", *argv, "--out", str(tmp_path / "s")]) == cli.EXIT_ERROR
    out, err = capsys.readouterr()
    lines = err.strip().splitlines()
    assert out == "" and len(lines) == 1 and lines[0].startswith("nsfem: error:"), err
    assert words in lines[0]
    assert not (tmp_path / "s").exists()


def test_parse_ranges_integers_and_floats():
    fixed, axes = parse_ranges(["mesh.elements=20:40:3", "rotation.speed_hz=10:11:3", 'initial.state="rest"'])
    assert fixed == ['initial.state="rest"']
    assert axes[0].values == (20, 30, 40) and all(isinstance(v, int) for v in axes[0].values)
    assert axes[1].values == (10.0, 10.5, 11.0)


def test_friction_sweep_equals_single_runs(client, tmp_path):
    # friction enters the contact set through the model's stack: one model per value, else the
    # 0.3 run would silently reuse the frictionless model
    base = BASE + ["rotation.speed_hz=15"]
    res = run_sweep(None, base + ["delamination.0.friction=0:0.3:2"], tmp_path, client=client, plot=False)
    assert not res.failed and res.info["models_built"] == 2
    refs = []
    for point, row in zip(res.points, res.runs):
        value = point["delamination.0.friction"]
        ref, _ = run_scene(nsfem.load_scene(None, base + [f"delamination.0.friction={value}"]))
        refs.append(ref)
        got, _, _ = Result.load(row["result"])
        _assert_same_run(got, ref, ("t", "q", "v", "gap", "normal_force", "tangential_force", "state"))
    # friction matters here (1.2e-3 of the largest gap), far above the tolerance: the comparison can fail
    assert np.abs(refs[0].gap - refs[1].gap).max() > 1e-4 * np.abs(refs[0].gap).max()


def _wait_idle(client, timeout=60.0):
    import time

    t0 = time.monotonic()
    while any(client.processing().values()) and time.monotonic() - t0 < timeout:
        time.sleep(0.1)


def test_interrupted_sweep_keeps_finished_rows_and_resumes(client, tmp_path):
    from nsfem.sweep import SweepInterrupted, run_name

    # many more values than workers: runs take ~0.1-0.3 s each, so with 2 workers the cancel (one
    # scheduler round trip after the first row) must come 7 run times late for all 16 to finish
    speeds = np.linspace(15, 25, 16)
    args = BASE + ["rotation.speed_hz=15:25:16"]

    def stop(line):
        if line.startswith("["):       # the first finished run (not the plan's line)
            raise KeyboardInterrupt

    with pytest.raises(SweepInterrupted) as info:
        run_sweep(None, args, tmp_path, client=client, progress=stop)
    assert info.value.result.info["interrupted"] is True
    with open(tmp_path / "sweep.csv") as fh:
        rows = list(csv.DictReader(fh))
    payload = json.loads((tmp_path / "sweep.json").read_text())
    assert len(rows) == 1 and rows[0]["error"] == "" and payload["interrupted"] is True
    assert len(payload["runs"]) == 1 and payload["values"] == [float(rows[0]["rotation.speed_hz"])]
    assert payload["runs"][0]["result"] == rows[0]["result"]
    _wait_idle(client)  # a run already started on a worker finishes and is kept
    # the interrupted run, the ones running on the 2 workers and any that finished before the cancel
    # arrived (how many is timing: on a loaded machine several); the pending rest is cancelled
    names = {run_name(p) for p in info.value.result.points}
    done = sum((tmp_path / n / "record.json").is_file() for n in names)
    assert len(names) == len(speeds) and 1 <= done < len(speeds)
    again = run_sweep(None, args, tmp_path, client=client, plot=False)
    assert again.info["resumed"] == done and again.info["executed"] == len(speeds) - done and not again.failed
    assert len(json.loads((tmp_path / "sweep.json").read_text())["runs"]) == len(speeds)


def test_model_build_failure_fails_its_rows_only(inprocess, tmp_path):
    res = run_sweep(None, ["mesh.elements=12", "simulation.t_end=0.02", "reduction.modes=16:400:2"], tmp_path,
                    client=inprocess, plot=False)
    ok, bad = res.runs
    assert ok["error"] == "" and ok["completed"] is True
    assert bad["error"].startswith("model build failed: reduction.modes = 400 exceeds")
    assert res.info["models_built"] == 1 and len(res.failed) == 1


def test_scheduler_without_workers_is_one_line(tmp_path, capsys, monkeypatch):
    distributed = pytest.importorskip("distributed")
    monkeypatch.setattr(ASSEMBLE, "build_model", lambda *a: pytest.fail("built a model before connecting"))
    monkeypatch.setattr(importlib.import_module("nsfem.sweep"), "CONNECT_TIMEOUT", 1.0, raising=False)
    with distributed.LocalCluster(n_workers=0, processes=False, dashboard_address=":0") as empty:
        argv = ["sweep", "--set", "rotation.speed_hz=10:20:2", "--scheduler", empty.scheduler_address,
                "--out", str(tmp_path / "s")]
        assert cli.main(argv) == cli.EXIT_ERROR
    out, err = capsys.readouterr()
    assert out == "" and err.count("\n") == 1 and f"--scheduler {empty.scheduler_address}: no worker" in err
    assert not (tmp_path / "s").exists()


def test_cli_sweep_scene_without_contacts(tmp_path, capsys):
    scene = tmp_path / "plain.toml"
    scene.write_text('title = "plain shaft"\n[shaft]\nlength = 1.0\n')
    argv = ["sweep", str(scene), "--set", "mesh.elements=12", "--set", "simulation.t_end=0.02", "--set",
            "rotation.speed_hz=10:20:2", "--workers", "1", "--out", str(tmp_path / "s")]
    assert cli.main(argv) == 0
    out, err = capsys.readouterr()
    assert out.count("no contacts") == 2 and "wrote" in out


def test_folder_table_covers_every_sweep_into_it(inprocess, tmp_path):
    fixed = ["mesh.elements=12", "simulation.t_end=0.02"]
    run_sweep(None, fixed + ["rotation.speed_hz=10:30:3"], tmp_path, client=inprocess, plot=False)
    # a finer range later, the fixed settings reordered plus a no-op override: the same sweep
    fine = run_sweep(None, ["simulation.t_end=0.02", "mesh.elements=12", "damping.external=0.0",
                            "rotation.speed_hz=15:25:2"], tmp_path, client=inprocess)
    assert fine.info["executed"] == 2
    with open(tmp_path / "sweep.csv") as fh:
        assert [float(r["rotation.speed_hz"]) for r in csv.DictReader(fh)] == [10, 15, 20, 25, 30]
    payload = json.loads((tmp_path / "sweep.json").read_text())
    assert payload["values"] == [10, 15, 20, 25, 30] and len(payload["runs"]) == 5
    assert [p["rotation.speed_hz"] for p in fine.points] == [10, 15, 20, 25, 30]


def test_a_rotor_sweep_records_its_sensors_steady_amplitudes(inprocess, tmp_path):
    """The shipped critical_speed rotor (no contacts): each run's row holds its probes' amplitudes over
    the last half of the run, which equal the steady unbalance response of the linear system (the
    harmonic solve of (-w^2 M + i w C + Q) X = fc - i fs) once the start has decayed (its slowest
    lateral mode decays at 5 1/s: e^-20 by the last half's start; 1e-4 leaves room for that and the
    sampling of the peaks, 1 ms against 26 to 31 Hz)."""
    import math

    from nsfem import load_scene
    from nsfem.fem.rotating import rotor_operators
    from nsfem.sensors import hermite_row
    from nsfem.simulate import run_scene
    from nsfem.system import linear_system

    res = run_sweep("critical_speed", ["rotation.speed_hz=26:31:2"], tmp_path, client=inprocess)
    text = (tmp_path / "sweep.csv").read_text().splitlines()
    assert "amplitude_disk_y_m" in text[0] and "amplitude_disk_z_m" in text[0]
    for speed, row in zip((26.0, 31.0), res.runs):
        _, system = run_scene(load_scene("critical_speed", [f"rotation.speed_hz={speed}", "simulation.t_end=0.01"]))
        model, red = system.info["model"], system.info["reduction"]
        s = linear_system(rotor_operators(model, red.T), speed, frame="inertial")
        w = 2 * math.pi * speed
        X = np.linalg.solve(-w**2 * s.M.toarray() + 1j * w * s.C.toarray() + s.Q.toarray(), s.fc - 1j * s.fs)
        for field, name in (("V", "disk_y"), ("W", "disk_z")):
            steady = abs((hermite_row(model, "intact_0", field, 0.5) @ np.asarray(red.T)) @ X)[0]
            assert row[f"amplitude_{name}_m"] == pytest.approx(steady, rel=1e-4)
    assert res.figure is not None and res.figure.exists()
