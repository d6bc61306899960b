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
        # the counts and maxima of `run --json` (issue 34), per part too: one definition, the same numbers
        for key in ("impacts", "shared_impacts", "max_impulse_Ns", "parts"):
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
    lines = out.splitlines()
    # no contact columns that all read "no contacts", and the note on what would give amplitudes
    assert "no contacts" not in out.replace("no contacts and no [[sensor]]", "")
    assert lines[1].startswith("no contacts and no [[sensor]]") and lines[2].split() == ["rotation.speed_hz"]
    assert [line.split() for line in lines[3:5]] == [["10"], ["20"]] and lines[5].startswith("wrote")


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
    """The shipped critical_speed rotor (no contacts): each run's row holds its probes' 1x amplitude and
    phase lag, fitted over whole periods of the last half of the run, which equal the steady unbalance
    response of the linear system (the harmonic solve of (-w^2 M + i w C + Q) X = fc - i fs: the probe
    reads Re(z e^{i w t}) = |z| cos(w t - phi), phi = -arg z) once the start has decayed. The fit is exact
    for the harmonic (round-off), so what is left is the start: its slowest lateral mode decays at
    5 1/s, e^-20 = 2e-9 of it by the last half's start (measured 1e-11); 1e-8 in amplitude and 1e-8 rad
    (6e-7 deg) in phase bound that. (Half the sampled peak-to-peak, the former amplitude, was off by
    1.5e-5: the samples miss the peaks.)"""
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
            z = ((hermite_row(model, "intact_0", field, 0.5) @ np.asarray(red.T)) @ X)[0]
            assert row[f"amplitude_{name}_m"] == pytest.approx(abs(z), rel=1e-8)
            lag = (row[f"phase_{name}_deg"] + math.degrees(np.angle(z)) + 180.0) % 360.0 - 180.0
            assert abs(lag) < math.degrees(1e-8)
        assert not row["warnings"]      # steady: no row says otherwise
    assert "phase_disk_y_deg" in text[0] and res.figure is not None and res.figure.exists()


# --- issue 34: the sweep table for rotors (1x amplitudes fitted, contact columns only with contacts) ---

def test_harmonic_fit_of_a_sampled_sinusoid_is_exact_where_half_the_peak_to_peak_is_low():
    """A sinusoid sampled 40 times a period with its peaks midway between two samples: half the sampled
    peak-to-peak is A cos(pi f dt) (low by 1 - cos(pi / 40) = 3.1e-3, the old sweep amplitude's error),
    while the least-squares harmonic over whole periods returns A and the phase lag exactly; an offset
    and the 2x and 3x harmonics (a crack's, a rub's) do not enter it, their samples being orthogonal to
    1x over whole periods. Tolerance: the fit is a 3-column least squares with orthogonal columns
    (condition sqrt(2)) on 400 samples: round-off of order 400 eps = 1e-13; 1e-12 leaves margin."""
    from nsfem.analysis.harmonic import amplitude_phase, harmonic_fit, whole_periods

    f, per, A, c = 25.0, 40, 3.0e-5, -2.0e-4
    dt = 1.0 / (f * per)
    t = np.arange(10 * per + 1) * dt                      # 10 periods, both ends sampled
    lag = np.pi / per                                     # the peak half a sample after t = 0
    pure = A * np.cos(2 * np.pi * f * t - lag)
    assert np.ptp(pure) / 2 == pytest.approx(A * np.cos(np.pi * f * dt), rel=1e-12)
    assert 1 - np.ptp(pure) / (2 * A) == pytest.approx(1 - np.cos(np.pi / per), rel=1e-6)    # 3.08e-3 low
    window = whole_periods(t, f, share=0.5)
    assert window.sum() == 5 * per                        # 5 whole periods, each sample once
    others = c + 0.7 * A * np.cos(4 * np.pi * f * t + 0.3) + 0.2 * A * np.sin(6 * np.pi * f * t)
    for x in (pure, pure + others):
        amp, phi = amplitude_phase(harmonic_fit(t[window], x[window], f))
        assert amp == pytest.approx(A, rel=1e-12) and phi == pytest.approx(np.degrees(lag), rel=1e-12)
    # theta0 (rotation.phase_deg: the angle at t = 0) moves the mark: the peak lags the angle's zero by 30 deg more
    amp, phi = amplitude_phase(harmonic_fit(t[window], pure[window], f, theta0=np.radians(30.0)))
    assert phi == pytest.approx(np.degrees(lag) + 30.0, rel=1e-12)


@pytest.mark.parametrize("overrides, amplitudes, words", [
    # the start decays at 5 1/s: 5 % change of the vertical probe's 1x between 0.3-0.45 s and 0.45-0.6 s
    # (the horizontal one's, 3e-5, is steady enough)
    (["simulation.t_end=0.6"], True, "sensor disk_z: its 1x amplitude changes by"),
    (["simulation.t_end=0.05"], False, "less than one period"),           # 0.025 s against 1/26 s
    (["simulation.output_dt=0.02"], False, "samples a period"),           # 1.9 samples a period
    (["rotation.speed_hz=0", "simulation.t_end=0.2"], False, None),         # no rotation, no 1x (and no warning)
], ids=["not-steady", "short", "coarse", "at-rest"])
def test_sensor_amplitudes_say_when_the_run_cannot_give_them(overrides, amplitudes, words):
    from nsfem.sweep import sensor_amplitudes

    scene = nsfem.load_scene("critical_speed", ["simulation.t_end=0.3", *overrides])
    result, system = run_scene(scene, progress=False)
    said = []
    amps = sensor_amplitudes(result, system, said.append)
    assert set(amps) == {"amplitude_disk_y_m", "phase_disk_y_deg", "amplitude_disk_z_m", "phase_disk_z_deg"}
    assert all((v is not None) == amplitudes for v in amps.values())
    assert (words is None and not said) or (said and all(words in w for w in said)), said


def test_sweep_table_lines_columns_and_digits():
    from nsfem.sweep import table_lines, value_digits

    rotor = [{"s": s, "min_gap_m": None, "events": 0, "amplitude_probe_m": a, "phase_probe_deg": p, "error": ""}
             for s, a, p in ((10, 4.222581371620753e-06, 9.7143), (13.181818181818, 8.53053226944922e-06, 15.03))]
    lines = table_lines(["s"], rotor + [{"s": 45, "error": "boom\\n here"}])
    assert "1x" in lines[0] and "whole periods" in lines[0]                # what the amplitude is
    assert lines[1].split() == ["s", "probe", "[m]", "probe", "[deg]"]     # no contact columns
    assert lines[2].split() == ["10", "4.22258e-06", "9.7"] and lines[3].split()[0] == "13.1818"
    assert lines[4].split()[:2] == ["45", "failed:"]
    assert lines[1].index("probe [m]") == lines[2].index("4.22")
    assert lines[1].index("probe [deg]") == lines[3].index("15.0")
    # with contacts: their columns, then the sensors'
    touch = dict(rotor[0], min_gap_m=-1e-9, max_gap_m=2e-4, closed_fraction=0.25, max_normal_force_N=12.5, events=7)
    head = table_lines(["s"], [touch])[1]
    assert "closed [%]" in head and head.index("max force [N]") < head.index("probe [m]")
    assert table_lines(["s"], [touch])[2].split()[1:4] == ["7", "-", "25"]
    # a run of impacts only (no sustained force): the table counts them as the run's summary does, beside
    # its 0 N of sustained force (it printed events and "max force 0" alone)
    knock = dict(touch, events=11, impacts=9, max_normal_force_N=0.0)
    head, row = table_lines(["s"], [knock])[1:3]
    assert "impacts" in head and row.split()[1:3] == ["11", "9"]
    # values that 6 digits would print alike get the digits that tell them apart (a folder's 12 at most)
    assert value_digits([1.0, 1.0000001, 2]) == 8 and value_digits([1.0, 1.0 + 1e-13]) == 12


def test_records_of_the_old_amplitude_are_run_again(tmp_path):
    """A record whose row has sensor amplitudes of the former definition (half the peak-to-peak, no
    stamp) is not a finished run of this version: resumed, it would mix two measures in one table."""
    from nsfem.sweep import AMPLITUDE_FIT, folder_rows, read_record

    run = tmp_path / "s=1"
    run.mkdir()
    (run / "result.npz").write_bytes(b"x")
    row = {"s": 1, "error": "", "result": str(run / "result.npz"), "completed": True, "amplitude_a_m": 1e-6}
    for stamp, current in ((None, False), (AMPLITUDE_FIT, True)):
        rec = {"fingerprint": "fp", "point": {"s": 1}, "row": row, **({"amplitudes": stamp} if stamp else {})}
        (run / "record.json").write_text(json.dumps(rec))
        assert (read_record(run, "fp") is not None) == current
        assert len(folder_rows(tmp_path, "fp", ["s"])) == current
    # a row without sensor amplitudes has nothing to mix: an unstamped one stays valid
    row.pop("amplitude_a_m")
    (run / "record.json").write_text(json.dumps({"fingerprint": "fp", "point": {"s": 1}, "row": row}))
    assert read_record(run, "fp") is not None


# --- issue 34 review (r2): the 1x phase against a closed form ---

JEFFCOTT = """
title = "Jeffcott rotor: 10 kg disk at the middle of a short stiff shaft on two damped isotropic bearings"
[shaft]
length = 0.2
section = "circle"
diameter = 0.1
E = 2.1e11
rho = 10.0
supports = "free-free"
[beam]
theory = "euler-bernoulli"
[[disk]]
x = 0.1
mass = 10.0
polar_inertia = 0.02
diametral_inertia = 0.01
[[bearing]]
x = 0.0
kyy = 5e5
kzz = 5e5
cyy = 200.0
czz = 200.0
[[bearing]]
x = 0.2
kyy = 5e5
kzz = 5e5
cyy = 200.0
czz = 200.0
[[bearing]]
x = 0.0
kxx = 1e6
[[unbalance]]
x = 0.1
magnitude = 1e-4
phase_deg = 40.0
[[sensor]]
name = "y"
x = 0.1
direction = "+y"
[[sensor]]
name = "z"
x = 0.1
direction = "+z"
[[sensor]]
name = "down"
x = 0.1
direction = "-z"
[rotation]
frame = "inertial"
phase_deg = 25.0
[initial]
state = "stationary"
[mesh]
elements = 4
[reduction]
method = "none"
[simulation]
t_end = 2.0
output_dt = 5e-4
[output]
plots = []
vtu_every = 0
"""


@pytest.mark.parametrize("frame", ["inertial", "rotating"])
@pytest.mark.parametrize("speed", [40.0, 60.0])
def test_sweep_phase_is_the_jeffcott_lag_behind_the_unbalance(tmp_path, speed, frame):
    """Each sensor's phase_<sensor>_deg is the hand-computed lag of the Jeffcott rotor: the disk (m = 10 kg
    + the shaft's 0.016 kg, moving rigidly) on the shaft's central stiffness ks = 48 E I / L^3 in series with
    the two bearings (k = 1e6 N/m, c = 400 N s/m together); at the disk z = m e w^2 / D with
    D = ks - ks^2 / (ks + k + i w c) - m w^2, which is k - m w^2 + i c w for a rigid shaft (lag
    atan2(c w, k - m w^2)). The lag is measured from the unbalance's angle: +y reads
    |z| cos(theta + phase_u - lag), so phase_y = lag - phase_u whatever rotation.phase_deg (25 deg, in
    theta at t = 0 and in the unbalance's start alike); +z is a quarter period later (forward whirl),
    -z half a period after +z. Below (40 Hz) and above (60 Hz) the 50 Hz resonance (lag < and > 90 deg), computed
    in either frame (the probes read in the inertial one: the rotating run's signals are turned by theta).
    Tolerance: the closed form lumps the shaft's mass (1.6e-3 of m) into the disk and its bending is
    1.6e-4 of the bearings' compliance, a 3e-7 effect; the start decays at c / 2m = 20 1/s, e^-20 = 2e-9
    by the fitted last second; the fit itself is exact (round-off): 1e-5 relative and 1e-5 rad (6e-4 deg)
    bound both (measured at most 5.7e-7 and 2.9e-7 rad)."""
    import cmath
    import math

    from nsfem.sweep import sensor_amplitudes

    path = tmp_path / "jeffcott.toml"
    path.write_text(JEFFCOTT)
    scene = nsfem.load_scene(str(path), [f"rotation.speed_hz={speed}", f"rotation.frame={frame}"])
    warnings: list[str] = []
    row = sensor_amplitudes(*run_scene(scene), warnings.append)
    assert warnings == []
    mass = 10.0 + 10.0 * math.pi * 0.05**2 * 0.2
    ks = 48 * 2.1e11 * (math.pi * 0.1**4 / 64) / 0.2**3
    w = 2 * math.pi * speed
    z = 1e-4 * w**2 / (ks - ks**2 / (ks + 1e6 + 1j * w * 400.0) - mass * w**2)
    lag = -math.degrees(cmath.phase(z))
    assert (lag < 90.0) == (speed < 50.0)
    for name, shift in (("y", 0.0), ("z", 90.0), ("down", 270.0)):
        assert row[f"amplitude_{name}_m"] == pytest.approx(abs(z), rel=1e-5)
        off = (row[f"phase_{name}_deg"] - (lag - 40.0 + shift) + 180.0) % 360.0 - 180.0
        assert abs(off) < math.degrees(1e-5), (name, row[f"phase_{name}_deg"], lag)
