"""nsfem periodic --continue (a scene's branch of periodic orbits, nsfem.periodic.scene_branch) and nsfem sweep
--steady periodic (issue 36, items 2 and 3).

References: on a linear scene every orbit is the harmonic steady state, so the branch over speed is ``nsfem
response``'s resonance curve (and the section states the harmonic balance's, solved directly); a non-smooth
branch (a rigid stop struck once a period) is checked by what each of its points must satisfy: the exact flow
over one period returns to it."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from nsfem import cli, load_scene
from nsfem.periodic.scene_branch import branch_of_scene
from tests.test_periodic_cli import LINEAR, harmonic_state

#: a rigid stop 20 um beside the linear scene's disk (restitution 0.5): struck once a period below 22 Hz
STOP = [*LINEAR, "obstacle.0.x=0.5", "obstacle.0.normal=+y", "obstacle.0.clearance=2e-5",
        "obstacle.0.restitution=0.5"]


def _sets(overrides) -> list[str]:
    return sum((["--set", s] for s in overrides), [])


@pytest.fixture(scope="module")
def linear_branch():
    scene = load_scene("critical_speed", LINEAR)
    return scene, branch_of_scene(scene, "rotation.speed_hz", 24.0, 28.0, transient_periods=0)


def test_a_linear_branch_over_speed_is_nsfem_response(linear_branch):
    """Each point of the branch is the harmonic steady state at its speed: its section state that of the harmonic
    balance, its amplitudes those of nsfem response; no bifurcation; both sides reach their ends."""
    from nsfem.analysis.response import response_report
    from nsfem.integrate import ContactSystem

    scene, sb = linear_branch
    assert [s["stop"] for s in sb.sides] == ["end", "end"] and sb.stop == "end"
    assert sb.bifurcations == [] and sb.doubled == []
    values = [p["value"] for p in sb.points]
    assert values[0] == 24.0 and values[-1] == 28.0 and 26.0 in values and np.all(np.diff(values) > 0)
    model, red = sb.start.system.info["model"], sb.start.system.info["reduction"]
    rep = response_report(scene, model, np.array(values), red)
    for k, p in enumerate(sb.points):
        assert p["converged"] and p["stable"] and p["events_per_period"] == 0
        assert p["period_s"] == pytest.approx(1.0 / p["value"], rel=1e-15)
        system = ContactSystem.from_scene(scene, model, red, speed_hz=p["value"])
        q, v = harmonic_state(system, p["t0_s"])
        # the corrector's tolerance (1e-9 of the orbit's size) bounds the distance to the fixed point, times the
        # condition of (Phi - I) (~1e1 here: the multipliers' moduli are <= 0.984): within 1e-8 of its size
        assert np.abs(p["q0"] - q).max() <= 1e-8 * np.abs(q).max()
        assert np.abs(p["v0"] - v).max() <= 1e-8 * np.abs(v).max()
        for name, a in p["amplitudes"].items():
            # half the peak-to-peak, its extremes refined by a parabola through samples 2 pi / 256 apart: off by at
            # most h^4 / 24 = 1.5e-8 of the amplitude (test_periodic_cli), plus the state's 1e-8
            assert a == pytest.approx(rep["sensors"][name]["amplitude_m"][k], rel=3e-8)
        # a damped linear system: every multiplier exp(lambda T) inside the unit circle
        assert 0.0 < p["largest_multiplier"] < 1.0


def test_the_branch_json_keeps_the_contract_keys(linear_branch):
    """design.md section 9: ``branch`` (each point with the key's value, period_s, converged, residual,
    multipliers, stable, amplitudes) and ``bifurcations``; strict JSON (no arrays, no NaN)."""
    _, sb = linear_branch
    payload = json.loads(json.dumps(sb.to_json(), allow_nan=False))
    for p in payload["branch"]:
        assert {"rotation.speed_hz", "period_s", "converged", "residual", "multipliers", "stable",
                "amplitudes", "events_per_period"} <= set(p)
        assert p["residual"] <= 1e-9 and all(len(z) == 2 for z in p["multipliers"])
    assert payload["bifurcations"] == [] and payload["stop"] == "end"


@pytest.fixture(scope="module")
def stop_branch():
    scene = load_scene("critical_speed", STOP)
    return scene, branch_of_scene(scene, "rotation.speed_hz", 20.0, 22.0, transient_periods=0)


def test_a_branch_with_an_impact_a_period_consists_of_orbits(stop_branch):
    """The scene's speed (26 Hz) lies outside 20:22: the branch starts at the nearer end, 22 Hz, and runs to
    20 Hz. Each point is an orbit: the exact flow over its period from its section state returns to it (the
    corrector's tolerance, 1e-9 of its size, and the flow's event times, located to ~1e-13 s: 1e-8 of the size
    is far above both), striking the stop once."""
    from nsfem.integrate import ContactSystem
    from nsfem.periodic.flow import flow

    scene, sb = stop_branch
    assert sb.start_value == 22.0 and sb.scene_value == 26.0 and [s["towards"] for s in sb.sides] == [20.0]
    # the impact drifts towards the start's section along 20:22 (within a quarter period of it by 21.96 Hz): the
    # section moves, listed, and the points after it carry the new one
    (side,) = sb.sides
    assert side["reanchors"] and len({p["t0_s"] for p in sb.points}) == len(side["reanchors"]) + 1
    assert sb.stop == "end" and sb.points[0]["value"] == 20.0 and sb.points[-1]["value"] == 22.0
    model, red = sb.start.system.info["model"], sb.start.system.info["reduction"]
    for p in sb.points:
        assert p["converged"] and p["events_per_period"] >= 1
        # (at the point's own section: it moves off the impact as that drifts with the speed)
        fl = flow(ContactSystem.from_scene(scene, model, red, speed_hz=p["value"]), p["t0_s"], p["q0"],
                  p["v0"], p["period_s"], jacobian=False)
        assert np.abs(fl.q - p["q0"]).max() <= 1e-8 * np.abs(p["q0"]).max()
        assert sum(1 for e in fl.result.events if e.get("impact")) == 1
        # the disk cannot pass the stop: its y never exceeds the clearance by more than the impact's round-off
        assert p["amplitudes"]["disk_y"] > 0.0


def test_the_branch_amplitude_at_the_stop_is_the_stop(stop_branch):
    """review2: each point's disk_y amplitude is half of (the stop's 20 um, reached at the impact, minus the
    smallest y over the period), not of the sample before the impact (0.1 to 0.2 um short: the resonance curve
    was jagged point to point). Tolerance as in test_periodic_cli's single orbit: the gap closed to round-off,
    the smooth minimum refined to 1.5e-8 of the amplitude: 1e-11 m."""
    from nsfem.fem.constraints import dense
    from nsfem.integrate import ContactSystem
    from nsfem.periodic.flow import flow
    from nsfem.periodic.scene import _extreme
    from nsfem.sensors import read

    scene, sb = stop_branch
    model, red = sb.start.system.info["model"], sb.start.system.info["reduction"]
    rot = scene.rotation
    for p in sb.points:
        T = p["period_s"]
        fl = flow(ContactSystem.from_scene(scene, model, red, speed_hz=p["value"]), p["t0_s"], p["q0"],
                  p["v0"], T, jacobian=False, output_dt=T / 256)
        y = read(scene.sensors, model, dense(red.T), fl.result.t, fl.result.q, rot.frame, p["value"],
                 rot.phase_deg)[:-1, 0]
        low = -_extreme(y, -1.0)
        assert abs(p["amplitudes"]["disk_y"] - 0.5 * (2e-5 - low)) <= 1e-11, p["value"]


def test_an_interrupted_branch_keeps_its_points(monkeypatch):
    """Ctrl-C during the third point's report: the branch so far (two points, the start and one step) is returned,
    marked interrupted."""
    from nsfem.periodic import scene_branch

    real, calls = scene_branch._Family.point, []

    def point(self, *args, **kwargs):
        calls.append(1)
        if len(calls) == 3:
            raise KeyboardInterrupt
        return real(self, *args, **kwargs)

    monkeypatch.setattr(scene_branch._Family, "point", point)
    scene = load_scene("critical_speed", LINEAR)
    sb = branch_of_scene(scene, "rotation.speed_hz", 25.0, 27.0, transient_periods=0)
    assert sb.interrupted and sb.stop == "interrupted" and len(sb.points) == 2
    # the side towards LOW is listed in reverse (the branch in order of its values): its start last
    assert sb.points[-1]["value"] == 26.0 and sb.points[0]["value"] < 26.0


def test_other_keys_reload_the_scene_at_each_value():
    """A key other than the speed: the scene is loaded again at each value (``load``); a linear scene's branch
    over rotation.phase_deg (the unbalance's angle) keeps every amplitude (the orbit turns with it) and its speed's
    period."""
    scene = load_scene("critical_speed", LINEAR)
    sb = branch_of_scene(scene, "rotation.phase_deg", 0.0, 40.0, transient_periods=0, steps=4,
                         load=lambda extra: load_scene("critical_speed", [*LINEAR, *extra]))
    assert sb.start_value == 0.0 and sb.stop in ("end", "max_steps") and len(sb.points) >= 3
    a0 = sb.points[0]["amplitudes"]
    for p in sb.points:
        assert p["period_s"] == pytest.approx(1 / 26.0, rel=1e-15) and p["converged"]
        # an amplitude does not depend on the forcing's phase: only the orbit's own accuracy (1e-8) is left
        for name, a in p["amplitudes"].items():
            assert a == pytest.approx(a0[name], rel=3e-8)


def test_a_key_other_than_the_speed_needs_a_loader():
    scene = load_scene("critical_speed", LINEAR)
    from nsfem.errors import NsfemError

    with pytest.raises(NsfemError, match="give load"):
        branch_of_scene(scene, "rotation.phase_deg", 0.0, 40.0)


def test_cli_continue_writes_branch_json_npz_png_and_a_table(tmp_path, capsys):
    from nsfem.plot.periodic import key_label

    out = tmp_path / "b"
    argv = ["periodic", "critical_speed", *_sets(STOP), "--continue", "rotation.speed_hz=21.5:22", "--out", str(out)]
    assert cli.main([*argv, "--json", "--transient", "0"]) == 0
    payload = json.loads(capsys.readouterr().out)
    assert sorted(p.name for p in out.iterdir() if not p.name.startswith(".")) == ["branch.json", "branch.npz",
                                                                                   "branch.png"]
    assert json.loads((out / "branch.json").read_text())["branch"] == payload["branch"]
    with np.load(out / "branch.npz") as z:
        assert np.array_equal(z["value"], [p["rotation.speed_hz"] for p in payload["branch"]])
        assert z["q0"].shape == z["v0"].shape and z["q0"].shape[0] == len(payload["branch"])
        assert list(z["sensors"]) == ["disk_y", "disk_z"]
        assert np.array_equal(z["amplitudes"][:, 0], [p["amplitudes"]["disk_y"] for p in payload["branch"]])
        assert json.loads(str(z["meta"]))["key"] == "rotation.speed_hz"
        # each point's section time (it moves off the stop's impact as that drifts with the speed)
        assert np.array_equal(z["t0_s"], [p["t0_s"] for p in payload["branch"]])
        assert float(z["t0"]) == payload["branch"][-1]["t0_s"]   # (the start: 22 Hz, followed towards 21.5)
    assert payload["bifurcations"] == [] and payload["stop"] == "end"
    assert key_label("rotation.speed_hz") == "rotor speed [Hz]"
    # the text: a row per point and the bifurcations' line
    assert cli.main([*argv, "--transient", "0"]) == 0
    text = capsys.readouterr().out
    assert "bifurcations: none found" in text and sum(1 for ln in text.splitlines() if ln.strip().startswith(
        ("21.", "22"))) == len(payload["branch"])


def test_cli_interrupt_leaves_the_points_so_far(tmp_path, monkeypatch, capsys):
    """Ctrl-C during a branch: exit 130, branch.json and branch.npz hold the points found so far (valid files),
    stop "interrupted"."""
    from nsfem.periodic import scene_branch

    real, calls = scene_branch._Family.point, []

    def point(self, *args, **kwargs):
        calls.append(1)
        if len(calls) == 4:
            raise KeyboardInterrupt
        return real(self, *args, **kwargs)

    monkeypatch.setattr(scene_branch._Family, "point", point)
    out = tmp_path / "b"
    code = cli.main(["periodic", "critical_speed", *_sets(LINEAR), "--set", "output.plots=[]", "--continue",
                     "rotation.speed_hz=25:27", "--transient", "0", "--out", str(out)])
    assert code == 130 and "interrupted" in capsys.readouterr().err
    payload = json.loads((out / "branch.json").read_text())
    assert payload["stop"] == "interrupted" and len(payload["branch"]) == 3
    with np.load(out / "branch.npz") as z:
        assert z["value"].size == 3


def test_the_help_says_the_steps_the_library_uses(capsys):
    from nsfem.periodic import scene_branch

    with pytest.raises(SystemExit):
        cli.main(["periodic", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert f"(default {scene_branch.STEPS}, at most {scene_branch.STEPS_MAX})" in text
    assert cli.parser().parse_args(["periodic"]).steps == scene_branch.STEPS


def test_sweep_steady_periodic_is_nsfem_response(tmp_path):
    """sweep --steady periodic on the linear scene: per speed, the 1x fit over exactly one period of the orbit is
    the harmonic response (a Fourier coefficient over a whole period of uniform samples of a sinusoid: exact up to
    the orbit's 1e-8); phases likewise (1e-6 rad); the stability columns; a rerun resumes every value; a transient
    sweep is refused in its folder."""
    from nsfem.analysis.response import response_report
    from nsfem.errors import NsfemError
    from nsfem.fem.assemble import build_model
    from nsfem.reduce import scene_reduction
    from nsfem.sweep import run_sweep

    overrides = [*LINEAR, "output.plots=[]", "rotation.speed_hz=20:30:3"]
    res = run_sweep("critical_speed", overrides, tmp_path / "s", workers=1, steady="periodic", plot=False)
    assert res.info["steady"] == "periodic" and not res.failed
    scene = load_scene("critical_speed", LINEAR)
    model = build_model(scene)
    speeds = np.array([r["rotation.speed_hz"] for r in res.runs], dtype=float)
    rep = response_report(scene, model, speeds, scene_reduction(scene.reduction, model))
    for k, r in enumerate(res.runs):
        assert r["stable"] is True and r["converged"] is True and r["events_per_period"] == 0
        assert 0.0 < r["largest_multiplier"] < 1.0 and r["method"] == "exact"
        for name in ("disk_y", "disk_z"):
            assert r[f"amplitude_{name}_m"] == pytest.approx(rep["sensors"][name]["amplitude_m"][k], rel=1e-8)
            dphi = (r[f"phase_{name}_deg"] - rep["sensors"][name]["phase_deg"][k] + 180.0) % 360.0 - 180.0
            assert abs(math.radians(dphi)) <= 1e-6
    again = run_sweep("critical_speed", overrides, tmp_path / "s", workers=1, steady="periodic", plot=False)
    assert again.info["resumed"] == 3 and again.info["executed"] == 0 and again.runs == res.runs
    header = (tmp_path / "s" / "sweep.csv").read_text().splitlines()[0].split(",")
    assert {"stable", "largest_multiplier", "events_per_period", "converged"} <= set(header)
    with pytest.raises(NsfemError, match="another sweep"):
        run_sweep("critical_speed", overrides, tmp_path / "s", workers=1, plot=False)


def test_a_speed_range_ending_at_a_bearing_tables_end_is_named():
    """stepped_rotor's bearing tables end at 150 Hz: the continuation steps a little past its range's ends, so a
    range ending there is warned about (naming the table); one inside it is not."""
    from nsfem.periodic.scene_branch import table_edge

    scene = load_scene("stepped_rotor")
    assert table_edge(scene, 140.0, 150.0) == ("bearing.0.speeds_hz", 150.0)
    assert table_edge(scene, 10.0, 40.0) == ("bearing.0.speeds_hz", 10.0)
    assert table_edge(scene, 140.0, 149.0) is None


def test_a_speed_outside_the_range_starts_at_the_nearer_end_without_a_loader():
    """review2: branch_of_scene over the speed without ``load`` (the Python API's default: one model) found its
    first orbit at the scene's own speed (26 Hz, period 1/26 s) when that lies outside the range, and reported it
    as the start at 22 Hz. The start is the orbit at 22 Hz: its period 1/22 s and its flow over it returns to its
    state (the shooting's 1e-9)."""
    from nsfem.periodic.flow import flow

    scene = load_scene("critical_speed", LINEAR)
    sb = branch_of_scene(scene, "rotation.speed_hz", 21.5, 22.0, transient_periods=0, steps=2)
    o = sb.start.orbit
    assert sb.start_value == 22.0 and o.period_s == pytest.approx(1 / 22.0, rel=1e-15) and o.converged
    assert sb.start.system.omega == pytest.approx(2 * np.pi * 22.0, rel=1e-15)
    fl = flow(sb.start.system, o.t0, o.q0, o.v0, o.period_s, jacobian=False)
    assert np.abs(fl.q - o.q0).max() <= 1e-8 * np.abs(o.q0).max()


def test_a_doubled_branch_is_reported_at_its_own_section(monkeypatch):
    """review2: a doubled branch's sections are at its own t0 (OrbitBranch.t0: the shooting moves a section
    lying on an event), but its points' residual and amplitudes were computed by a flow from the first orbit's
    t0. A doubled branch stood in here (no scene of ours period-doubles in a test's time): the linear scene's
    orbit of period 2 T with its section a quarter period on; reported at its t0, its amplitudes are the single
    orbit's (one orbit, sampled from another phase: the parabola's 1.5e-8 at most, 1e-7 taken); from the first
    orbit's t0 they were a transient's, 11 % off."""
    from nsfem.periodic import branch as branch_module
    from nsfem.periodic.shooting import periodic_orbit

    real = branch_module.orbit_branch

    def with_a_doubled_branch(system_at, period_at, q0, v0, p0, p_end, **kw):
        br = real(system_at, period_at, q0, v0, p0, p_end, **kw)
        T = period_at(p0)
        start = br.points[0] if br.points[0]["value"] == p0 else br.points[-1]
        t_d = br.t0 + T / 4   # its section: a quarter period on (the orbit's state there by a flow)
        from nsfem.periodic.flow import flow

        there = flow(system_at(p0), br.t0, start["q0"], start["v0"], T / 4, jacobian=False)
        orb = periodic_orbit(system_at(p0), 2 * T, there.q, there.v, t_d)
        u = np.concatenate([orb.q0, orb.v0])
        bp = branch_module.OrbitPoint(p0, u, orb.multipliers, orb.stable, True, orb.residual, t0_s=orb.t0)
        kw["on_point"](bp, 2)
        point = {"value": p0, kw["key"]: p0, "q0": orb.q0, "v0": orb.v0, "converged": True, "residual": orb.residual,
                 "t0_s": orb.t0, "multipliers": [[float(z.real), float(z.imag)] for z in orb.multipliers]}
        moved = [{"index": 0, "value": p0, "t0_s": orb.t0, "forced": False}]   # (a section move, as one reports it)
        br.doubled.append(branch_module.OrbitBranch(kw["key"], 2, [point], [], "end", "", t0=orb.t0, reanchors=moved))
        return br

    monkeypatch.setattr(branch_module, "orbit_branch", with_a_doubled_branch)
    scene = load_scene("critical_speed", LINEAR)
    sb = branch_of_scene(scene, "rotation.speed_hz", 25.9, 26.0, transient_periods=0, steps=1)
    (d,) = sb.doubled
    (p,) = d["points"]
    for name, a in sb.start.amplitudes.items():
        assert p["amplitudes"][name] == pytest.approx(a, rel=1e-7), name
    # the doubled branch's section moves are reported as a side's
    assert d["reanchors"] == [{"value": 26.0, "t0_s": p["t0_s"], "forced": False}]


def test_a_periodic_sweep_rows_phase_is_the_lag_behind_the_unbalance(tmp_path):
    """review2: the 1x phase of a periodic sweep's row is the lag behind the rotation angle Omega t + phase_deg,
    as nsfem response's (and a transient sweep's): with the unbalance turned by 40 deg the lag is unchanged and the
    response's. The shipped scenes have phase_deg 0, where dropping the unbalance's angle from the fit passed every
    test. Tolerances: the orbit's 1e-8 on the amplitude, 1e-6 rad on the phase (as the sweep test above)."""
    from nsfem.analysis.response import response_report
    from nsfem.fem.assemble import build_model
    from nsfem.reduce import scene_reduction
    from nsfem.sweep import orbit_point

    scene = load_scene("critical_speed", [*LINEAR, "rotation.phase_deg=40", "rotation.speed_hz=24",
                                          "output.vtu_every=0"])
    row = orbit_point(scene, None, str(tmp_path), {"rotation.speed_hz": 24.0}, "fp")
    model = build_model(scene)
    rep = response_report(scene, model, np.array([24.0]), scene_reduction(scene.reduction, model))
    for name in ("disk_y", "disk_z"):
        assert row[f"amplitude_{name}_m"] == pytest.approx(rep["sensors"][name]["amplitude_m"][0], rel=1e-8)
        dphi = (row[f"phase_{name}_deg"] - rep["sensors"][name]["phase_deg"][0] + 180.0) % 360.0 - 180.0
        assert abs(math.radians(dphi)) <= 1e-6, name


def test_ctrl_c_inside_a_branch_flow_ends_the_branch(monkeypatch):
    """review2: Ctrl-C inside one of the continuation's flows ended that flow early (the integrator's clean stop),
    which the corrector took for a failed step: the branch went on, and the interrupt was lost. The signal raised
    at the 5th flow of the branch (inside the integrator's loop) ends it: interrupted, its points so far kept."""
    import signal

    from nsfem.integrate import event_driven
    from nsfem.periodic import branch as branch_module

    real_resolve, real_branch, calls = event_driven.resolve, branch_module.orbit_branch, []

    def resolve(*args, **kwargs):
        calls.append(1)
        if len(calls) == 5:
            signal.raise_signal(signal.SIGINT)
        return real_resolve(*args, **kwargs)

    def orbit_branch(*args, **kwargs):
        monkeypatch.setattr(event_driven, "resolve", resolve)
        return real_branch(*args, **kwargs)

    monkeypatch.setattr(branch_module, "orbit_branch", orbit_branch)
    scene = load_scene("critical_speed", LINEAR)
    # Ctrl-C's handler, even where the run started with SIGINT ignored (a job a non-interactive shell starts in the
    # background inherits SIG_IGN, which interrupts_end_flows rightly keeps: the signal then did nothing and the
    # branch ran to its end; this was the test's "flakiness", 1 of 1 runs under `sh -c 'pytest ... &'`)
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        sb = branch_of_scene(scene, "rotation.speed_hz", 25.0, 27.0, transient_periods=0, steps=20)
    finally:
        signal.signal(signal.SIGINT, previous)
    assert sb.interrupted and sb.stop == "interrupted"
    assert len(calls) == 5   # stopped there, not after the branch's other flows


# --- issue 36: continuation on Dask ---
# The independent pieces of a branch (the two sides of a start inside the range, the period-doubled branches) run
# as tasks on a Dask cluster (nsfem.periodic.branch_cluster). A task does the serial path's arithmetic on the
# same machine; only the BLAS threads may differ (the workers run one each, this process maybe more), which
# reorders sums: the points agree to round-off, amplified at most to the corrector's tolerance (1e-9 of the
# orbit's size) times the condition of Phi - I (~1e1 here, |mu| <= 0.98): 1e-8 of the size, the same steps taken.
@pytest.fixture(scope="module")
def dask_client():
    import logging

    from distributed import Client, LocalCluster

    cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0",
                           silence_logs=logging.ERROR, env={"OPENBLAS_NUM_THREADS": "1"})
    client = Client(cluster)
    yield client
    client.close()
    cluster.close()


def _same_points(a: list[dict], b: list[dict], span: float) -> None:
    """Two lists of branch points equal to round-off (see the block's comment)."""
    assert len(a) == len(b)
    for p, q in zip(a, b):
        assert abs(p["value"] - q["value"]) <= 1e-9 * span
        size = max(np.abs(p["q0"]).max(), 1e-300)
        assert np.abs(p["q0"] - q["q0"]).max() <= 1e-8 * size
        assert np.abs(p["v0"] - q["v0"]).max() <= 1e-8 * max(np.abs(p["v0"]).max(), 1e-300)
        assert p["stable"] == q["stable"] and p["converged"] == q["converged"]
        assert p["events_per_period"] == q["events_per_period"] and p["multiple"] == q["multiple"]
        for name, amp in p["amplitudes"].items():
            assert q["amplitudes"][name] == pytest.approx(amp, rel=1e-8)


def test_a_branch_on_a_two_worker_cluster_is_the_serial_branch(dask_client):
    """The linear scene from its 26 Hz over 25.6:26.4: both sides as tasks give the serial path's points in its
    order (LOW -> HIGH, the start once), its sides' stops and reasons, a progress line per point found (the start
    once per side, as serially)."""
    scene = load_scene("critical_speed", LINEAR)
    kw = dict(transient_periods=0, steps=3)
    serial_lines, lines = [], []
    serial = branch_of_scene(scene, "rotation.speed_hz", 25.6, 26.4, progress=serial_lines.append, **kw)
    sb = branch_of_scene(scene, "rotation.speed_hz", 25.6, 26.4, progress=lines.append, client=dask_client, **kw)
    assert serial.workers == 0 and sb.workers == 2 and not sb.interrupted
    assert [p["value"] for p in sb.points] == sorted(p["value"] for p in sb.points) and len(sb.points) >= 5
    _same_points(serial.points, sb.points, 0.8)
    assert sb.sides == serial.sides and sb.bifurcations == serial.bifurcations == [] and sb.doubled == []
    assert len(lines) == len(serial_lines) == len(sb.points) + 1
    assert dask_client.run(lambda: 1)   # the given client is left open


def test_an_interrupted_branch_on_a_cluster_keeps_its_points(dask_client):
    """Ctrl-C while the sides run on the cluster (raised here in the 3rd progress line, where the client waits):
    the tasks are cancelled, the branch so far (the points received: the start and at least one step) returned
    marked interrupted, in order along the branch; the given client is left usable."""
    scene = load_scene("critical_speed", LINEAR)
    calls = []

    def progress(line: str) -> None:
        calls.append(line)
        if len(calls) == 3:
            raise KeyboardInterrupt

    sb = branch_of_scene(scene, "rotation.speed_hz", 25.0, 27.0, transient_periods=0, steps=30, progress=progress,
                         client=dask_client)
    assert sb.interrupted and sb.stop == "interrupted" and 2 <= len(sb.points) <= 3
    values = [p["value"] for p in sb.points]
    assert values == sorted(values) and 26.0 in values
    assert dask_client.submit(sum, [1, 2], pure=False).result() == 3


class _ImpactFamily:
    """The impact oscillator (tests/impact_oscillator.py) over its forcing frequency w as a branch family of
    nsfem.periodic.scene_branch (system_at, period_at, point, fresh): points reported by their section state."""

    def system_at(self, w):
        from test_periodic_impact import OSC, impact_system

        return impact_system(OSC, w)

    def period_at(self, w):
        return 2 * math.pi / w

    def point(self, p, u, multiple, t0):
        n = u.size // 2
        return {"period_s": multiple * self.period_at(p), "residual": 0.0, "events_per_period": 0, "amplitudes": {},
                "multiple": int(multiple), "section_q_max": float(np.abs(u[:n]).max()), "q0": u[:n].copy(),
                "v0": u[n:].copy()}

    def fresh(self):
        return self


@pytest.mark.slow
def test_doubled_branches_on_a_cluster_are_the_serial_ones(dask_client):
    """The impact oscillator from w = 2.62 over 2.6:2.7: the side towards 2.7 period-doubles (closed form at
    2.658884546685); on the cluster the doubled branch is a task of its own, switched onto from the side's located
    bifurcation. Its points, the sides and the bifurcation are the serial orbit_branch's (the serial path of
    branch_of_scene: switching inside the side), to round-off (the block's comment; the period-2 orbit's
    multipliers stay below 0.7 in modulus past the flip)."""
    import warnings
    from types import SimpleNamespace

    from impact_oscillator import period1_branch
    from test_periodic_impact import OSC

    from nsfem.periodic.branch import orbit_branch
    from nsfem.periodic.branch_cluster import follow_sides
    from nsfem.periodic.scene_branch import _doubled, point_record, record_key

    family, p0, sides = _ImpactFamily(), 2.62, [2.6, 2.7]
    start = period1_branch(OSC, p0, -1)
    kw = dict(key="w", multiple=1, tol=1e-9, step=0.02, steps=6)
    serial: list = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for end in sides:
            records: dict = {}
            found: list = []

            def on_point(bp, m):
                rec = point_record(family, bp, m, "w", 0.0)
                records[record_key(m, bp.p, bp.u)] = rec
                found.append(rec)

            br = orbit_branch(family.system_at, family.period_at, [start.x0], [start.v0], p0, end, key="w",
                              t0=0.0, tol=1e-9, step=0.02, max_steps=6, on_point=on_point)
            # (each doubled point's record at its own section, as it came: the serial path's _doubled)
            serial.append((found, br, [_doubled(d, family, records) for d in br.doubled]))
    assert [b["kind"] for b in serial[1][1].bifurcations] == ["period-doubling"] and len(serial[1][2]) == 1

    got: dict = {0: [], 1: []}
    merged: list = []
    so = SimpleNamespace(orbit=SimpleNamespace(q0=np.array([start.x0]), v0=np.array([start.v0]), t0=0.0))
    follow_sides(dask_client, family, so, sides, p0, accept=lambda rec, m, k: got[k].append(rec),
                 merge=lambda k, stop, reason, bifs, doubled, moves=(): merged.append((k, stop, reason, bifs, doubled,
                                                                                       moves)), **kw)
    assert [m[0] for m in merged] == [0, 1]
    for k, (found, br, doubled) in enumerate(serial):
        _, stop, reason, bifs, dbl, moves = merged[k]
        assert (stop, reason) == (br.stop, br.reason)
        # the side's section moves, as the serial side's (where and to which section: round-off as the points')
        assert [(m["forced"], m["index"]) for m in moves] == [(m["forced"], m["index"]) for m in br.reanchors]
        for m, n in zip(moves, br.reanchors):
            assert abs(m["value"] - n["value"]) <= 1e-9 * 0.1 and abs(m["t0_s"] - n["t0_s"]) <= 1e-9
        assert [(b["kind"], "switch_failed" in b) for b in bifs] == [(b["kind"], "switch_failed" in b)
                                                                     for b in br.bifurcations]
        for b, c in zip(bifs, br.bifurcations):
            assert abs(b["value"] - c["value"]) <= 1e-9 * 0.1
        # each point as it came: the side's, then its doubled branch's (period 2)
        _same_points([r for r in found], got[k], 0.1)
        assert len(dbl) == len(doubled)
        for d, e in zip(dbl, doubled):
            assert d["multiple"] == e["multiple"] == 2 and (d["stop"], d["reason"]) == (e["stop"], e["reason"])
            _same_points(e["points"], d["points"], 0.1)


@pytest.mark.slow   # two commands each starting a cluster of two processes (10-20 s on a loaded machine)
def test_cli_workers_2_writes_the_serial_branch(tmp_path, capfd):
    """nsfem periodic --continue ... --workers 2: branch.json is the serial command's (points to round-off, the
    block's comment; every other key equal but the wall time, the outputs' folder and the workers); no log line
    of the cluster (its scheduler and workers write to this process's stderr) on the way."""
    argv = ["periodic", "critical_speed", *_sets(LINEAR), "--set", "output.plots=[]", "--continue",
            "rotation.speed_hz=25.6:26.4", "--steps", "3", "--transient", "0"]
    assert cli.main([*argv, "--out", str(tmp_path / "a")]) == 0
    capfd.readouterr()
    assert cli.main([*argv, "--out", str(tmp_path / "b"), "--workers", "2"]) == 0
    err = capfd.readouterr().err
    assert "Traceback" not in err and "ERROR" not in err and "distributed" not in err, err
    a, b = (json.loads((tmp_path / x / "branch.json").read_text()) for x in "ab")
    assert a["workers"] == 0 and b["workers"] == 2
    for key in set(a) - {"wall_s", "outputs", "workers", "branch"}:
        assert a[key] == b[key], key
    with np.load(tmp_path / "a" / "branch.npz") as za, np.load(tmp_path / "b" / "branch.npz") as zb:
        pts = [[{"value": v, "q0": q, "v0": w, "stable": p["stable"], "converged": p["converged"],
                 "events_per_period": p["events_per_period"], "multiple": p["multiple"], "amplitudes": p["amplitudes"]}
                for v, q, w, p in zip(z["value"], z["q0"], z["v0"], j["branch"])] for z, j in ((za, a), (zb, b))]
    _same_points(pts[0], pts[1], 0.8)


@pytest.mark.slow   # a cluster of two processes started, the branch under way, torn down: 10-20 s
def test_cli_sigterm_on_a_cluster_leaves_the_points_so_far_and_no_process(tmp_path):
    """SIGTERM to nsfem periodic --continue --workers 2 once points come: exit 130, branch.json valid with the
    points so far (stop "interrupted", the start among them), none of its processes (scheduler, nannies, workers)
    alive afterwards."""
    import sys

    from test_fuzz import _terminate_with_workers

    out = tmp_path / "b"
    argv = [sys.executable, "-m", "nsfem", "periodic", "critical_speed", *_sets(LINEAR), "--set", "output.plots=[]",
            "--continue", "rotation.speed_hz=20:32", "--steps", "10000", "--step", "1e-3", "--transient", "0",
            "--workers", "2", "--out", str(out)]
    _terminate_with_workers(argv, tmp_path, "nsfem periodic: rotation.speed_hz = ")
    payload = json.loads((out / "branch.json").read_text())
    values = [p["value"] for p in payload["branch"]]
    assert payload["stop"] == "interrupted" and 26.0 in values and values == sorted(values)
    with np.load(out / "branch.npz") as z:
        assert z["value"].size >= len(values)


def test_a_points_amplitudes_do_not_depend_on_its_section(stop_branch):
    """Amplitudes are reported from each point's own section (it moves along the branch): they are the orbit's,
    the same from any section. The point where the section moved, reported again from a third of a period on:
    amplitudes equal to the extremes' accuracy twice over: a smooth one refined to 1.5e-8 of the amplitude
    (test_periodic_cli), the stop's side as in test_the_branch_amplitude_at_the_stop_is_the_stop (1e-11 m): 2e-11 m;
    the largest |q| over the period (256 samples, the maximum's sampling error 1 - cos(pi / 256) = 7.5e-5 at a
    smooth peak) to 1e-4."""
    from nsfem.periodic.flow import flow
    from nsfem.periodic.scene_branch import _Family

    scene, sb = stop_branch
    family = _Family(scene, "rotation.speed_hz", sb.start.system, None)
    moved = sb.sides[0]["reanchors"][0]["value"]
    (p,) = [p for p in sb.points if p["value"] == moved]
    T = p["period_s"]
    there = flow(family.system_at(p["value"]), p["t0_s"], p["q0"], p["v0"], T / 3, jacobian=False)
    again = family.point(p["value"], np.concatenate([there.q, there.v]), 1, p["t0_s"] + T / 3)
    for name, a in p["amplitudes"].items():
        assert again["amplitudes"][name] == pytest.approx(a, rel=3e-8, abs=2e-11), name
    assert again["orbit_q_max"] == pytest.approx(p["orbit_q_max"], rel=1e-4)
    assert again["events_per_period"] == p["events_per_period"]


# --- issue 36: review A (continuation on Dask) ---
def _interrupt_at(n: int):
    """A progress callback raising KeyboardInterrupt (Ctrl-C) at its n-th line."""
    calls = []

    def progress(line: str) -> None:
        calls.append(line)
        if len(calls) == n:
            raise KeyboardInterrupt

    return progress


@pytest.mark.parametrize("on_cluster", [False, True])
def test_an_interrupted_branch_with_steps_does_not_say_before_the_first_step(on_cluster, request):
    """Ctrl-C at the 3rd progress line (the start and at least one step kept, no side finished): branch.json's
    reason says interrupted, never "interrupted before the first step", which only an interrupt with the start alone
    may say. On a cluster both sides run at once, so no side is finished when Ctrl-C comes: every interrupt."""
    client = request.getfixturevalue("dask_client") if on_cluster else None
    sb = branch_of_scene(load_scene("critical_speed", LINEAR), "rotation.speed_hz", 25.0, 27.0, transient_periods=0,
                         steps=30, progress=_interrupt_at(3), client=client)
    out = sb.to_json()
    assert sb.interrupted and len(sb.points) >= 2 and out["stop"] == "interrupted"
    assert "interrupted" in out["reason"] and "before the first step" not in out["reason"]


def test_a_branch_on_a_threaded_worker_counts_its_threads_and_is_the_serial_branch():
    """A cluster of one worker with two threads (a given client; --scheduler clusters are often so): both sides
    run at once in one process, sharing the scattered family; the points are the serial ones (the block's
    tolerance) and branch.json's ``workers`` counts the worker threads that followed it (2), as documented."""
    import logging

    from distributed import Client, LocalCluster

    scene = load_scene("critical_speed", LINEAR)
    kw = dict(transient_periods=0, steps=3)
    serial = branch_of_scene(scene, "rotation.speed_hz", 25.6, 26.4, **kw)
    with LocalCluster(n_workers=1, threads_per_worker=2, processes=False, dashboard_address=":0",
                      silence_logs=logging.ERROR) as cluster, Client(cluster) as client:
        sb = branch_of_scene(scene, "rotation.speed_hz", 25.6, 26.4, client=client, **kw)
    assert sb.workers == 2 and sb.to_json()["workers"] == 2
    _same_points(serial.points, sb.points, 0.8)
    assert sb.sides == serial.sides
