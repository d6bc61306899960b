"""Runs that cannot advance stop with a diagnosis and a valid partial result; long runs report
progress on stderr (issue 16; nsfem.integrate.guard, nsfem.integrate.base.Progress).

Tolerances: ``exact`` propagates a free mass as a polynomial and locates its events as polynomial
roots, so each flight time carries a few ulps; over the 64 flights kept before the guard stops, the
event times stay within 64 x 4 eps ~ 6e-14 of their closed form relative to the time reached
(allowed 1e-12; measured 1.1e-15). ``rk`` has no truncation error here: a force-free flight is a
straight line, which DOP853 integrates exactly, and its events are refined to round-off as well
(measured 1.6e-15): the same bounds. Elastic impacts (eps = 1) on one mass conserve the kinetic
energy exactly up to the impact LCP's round-off (~1e-15 relative, allowed 1e-12; measured 0).
"""

from __future__ import annotations

import io
import json
import math

import numpy as np
import pytest

from nsfem import cli
from nsfem.contact.set import ContactSet
from nsfem.errors import IntegrationError, NsfemError
from nsfem.integrate import ContactSystem, integrate
from nsfem.integrate.base import Progress
from nsfem.integrate.guard import WINDOW, same_time_limit
from nsfem.result import Result

RK = {"rtol": 1e-10, "atol": 1e-14}


def rattle(a: float = 5e-7, eps: float = 1.0) -> ContactSystem:
    """A unit mass between two stops at q = -a and q = +a (g0 = q + a, g1 = a - q), no forces."""
    cs = ContactSet.from_arrays(np.array([[1.0, -1.0]]), [a, a], eps=eps, labels=["lower stop", "upper stop"])
    return ContactSystem.from_arrays(M=[[1.0]], Q=[[0.0]], contacts=cs)


@pytest.mark.parametrize("method", ["exact", "rk"])
def test_rattling_mass_stops_with_a_diagnosis_after_one_window(method):
    """A mass rattling elastically between stops 1e-6 m apart at 1 m/s: an impact every 1e-6 s,
    1e5 events to t_end = 0.1 s, more than max_events = 5000. The old loop ran to max_events
    (the default 1e7: hours, the issue's rotor at 1e6 Hz); the pace guard stops after WINDOW
    events, naming the contacts and the events, with the closed-form motion up to there."""
    a, v0 = 5e-7, 1.0
    with pytest.raises(IntegrationError) as info:
        integrate(rattle(a), 0.1, method, output_dt=1e-6, v0=[v0], max_events=5000,
                  **(RK if method == "rk" else {}))
    msg = str(info.value)
    assert msg.startswith("no progress at t = ") and "\n" not in msg
    assert "lower stop" in msg and "upper stop" in msg and "impacts" in msg and "method moreau" in msg
    assert "needs about" in msg  # the projected number of events, against the limit
    res = info.value.result
    assert not res.completed and res.info["error"] == msg
    assert len(res.events) == WINDOW
    # closed form: the k-th impact at (2k + 1) a / v0 (first at the upper stop), speed kept
    t_ev = np.array([e["t"] for e in res.events])
    k = np.arange(t_ev.size)
    tol = 1e-12   # both methods: round-off only (module docstring)
    assert np.allclose(t_ev, (2 * k + 1) * a / v0, rtol=tol, atol=0.0)
    assert [e["contacts"] for e in res.events[:2]] == [[1], [0]]
    kin = np.array([i["kinetic_after_J"] for i in res.impacts])
    assert np.allclose(kin, 0.5 * v0 ** 2, rtol=1e-12)
    # the outputs up to the last one before the stop follow the rattle and are finite: they fall on
    # multiples of 2 a / v0, where the closed form passes q = 0, so each is off by v0 x the error of
    # the event times before it (tol x t; measured 1e-19 m against the allowed 6e-17 m)
    assert res.t.size > 1 and res.t[-1] <= t_ev[-1] and np.all(np.isfinite(res.q))
    assert np.all(np.abs(res.q) <= tol * t_ev[-1] * v0)


def test_an_impact_accumulation_is_not_mistaken_for_no_progress():
    """A ball dropped from h with restitution 0.9 bounces about 175 times before the Zeno rule
    (approach below 1e-8 of the first) makes it plastic: its last 64 impacts span 1e-4 of the
    first flight, a pace that projected to t_end exceeds 1e7 events. Their approach speeds fall
    (an accumulation): the guard lets it finish, at the closed-form accumulation time
    t_inf = sqrt(2 h / g) (1 + 2 e / (1 - e)) (the cut-off sequence ends at most 1e-8 x 2 e/(1-e) x
    sqrt(2 h / g) = 2.6e-8 s = 9.5e-9 t_inf early, measured 9.3e-9: allowed 2e-8 relative)."""
    g, h, e = 9.81, 0.1, 0.9
    cs = ContactSet.from_arrays([[1.0]], [0.0], eps=e)
    ball = ContactSystem.from_arrays(M=[[1.0]], Q=[[0.0]], f0=[-g], contacts=cs)
    t_inf = math.sqrt(2 * h / g) * (1 + 2 * e / (1 - e))
    res = integrate(ball, 1.5 * t_inf, "exact", output_dt=t_inf / 100, q0=[h])
    assert res.completed and len(res.impacts) > 2 * WINDOW
    assert res.impacts[-1]["t"] == pytest.approx(t_inf, rel=2e-8)
    assert res.state[0, -1] != 0   # resting on the stop at the end


def same_time_bound_examples():
    return [(0.5, 1e-8, 27), (0.9, 1e-8, 175), (0.0, 1e-8, 1), (1.0, 1e-8, 1)]


@pytest.mark.parametrize("eps, zeno, n_z", same_time_bound_examples())
def test_same_time_bound_counts_zeno_impacts_and_contact_states(eps, zeno, n_z):
    """n_z = ceil(ln zeno / ln eps) impacts before the Zeno rule (0.5: 27, the count quoted in
    transitions.py), plus 2 + 2 r states per contact; never below 200."""
    cs = ContactSet.from_arrays(np.eye(3)[:, :2], [0.0, 0.0], eps=eps, mu=0.3, r=8,
                                JS=[np.eye(3)[:, 2:3]] * 2)
    r = int(cs.r[0])
    assert same_time_limit(cs, zeno) == max(200, 2 * (n_z + 2 + 2 * r))
    many = ContactSet.from_arrays(np.eye(100), np.zeros(100), eps=eps)   # frictionless: r = 0
    assert int(many.r[0]) == 0 and same_time_limit(many, zeno) == max(200, 100 * (n_z + 2))


@pytest.mark.parametrize("method", ["exact", "rk"])
@pytest.mark.parametrize("mass, c, what", [(1.0, 1e300, "time resolution"), (1e-10, 1e308, "overflow")])
def test_absurd_damping_is_a_clean_error_not_a_crash_or_a_spin(method, mass, c, what):
    """damping.rayleigh = [1e300, 0] (C = 1e300 M: a rate of 1e300 1/s, an event-search step of
    1e-300 s: t + step == t, the old loop spun at t = 0) and [0, 1e300] (C = 1e300 K: C / m
    overflows; the old search divided by a zero step: ZeroDivisionError, here LinAlgError)."""
    cs = ContactSet.from_arrays([[1.0]], [1e-3], eps=0.5)
    sysm = ContactSystem.from_arrays(M=[[mass]], Q=[[1e8]], C=[[c]], f0=[-1.0], contacts=cs)
    with pytest.raises(IntegrationError) as info:
        integrate(sysm, 0.01, method, output_dt=1e-3, **(RK if method == "rk" else {}))
    msg = str(info.value)
    assert msg.startswith("no progress") and what in msg and "damping" in msg and "\n" not in msg
    assert info.value.result.t.size <= 1


@pytest.mark.parametrize("method", ["exact", "rk"])
def test_an_overflowing_state_stops_with_the_finite_outputs_kept(method):
    """q'' = 1e6 q (divergence at 1e3 1/s) from q0 = 1: q' = 1e3 sinh(1e3 t) overflows at
    t = (ln DBL_MAX + ln 2 - ln 1e3) / 1e3 = 0.7036 s. The old loop returned inf and NaN outputs
    as a completed run; now exact stops there with the outputs before it, on the closed form
    cosh(1e3 t) (1e-12 relative: the exponent 1e3 t carries a few ulps of the eigenvalue, times
    700 e-folds ~ 1e-13), and rk stops where its step size underflows (solve_ivp's own error),
    also before any non-finite output (its error control: 1e-6 here)."""
    sysm = ContactSystem.from_arrays(M=[[1.0]], Q=[[-1e6]])
    with pytest.raises(IntegrationError) as info:
        integrate(sysm, 1.0, method, output_dt=1e-2, q0=[1.0], **(RK if method == "rk" else {}))
    res = info.value.result
    t_of = (math.log(np.finfo(float).max) + math.log(2.0) - math.log(1e3)) / 1e3
    assert np.all(np.isfinite(res.q)) and np.all(np.isfinite(res.v)) and np.all(res.t < t_of)
    if method == "exact":
        assert str(info.value).startswith("the motion overflowed the floating-point range at t = 0.7")
        assert res.t[-1] > t_of - 0.01   # kept up to the last output before the overflow
    # exact: measured 2.2e-16; rk: its partial result holds no outputs at present, so for rk this
    # compares empty arrays
    assert np.allclose(res.q[0], np.cosh(1e3 * res.t), rtol=1e-12 if method == "exact" else 1e-6)


def test_penalty_with_absurd_damping_is_a_clean_error():
    cs = ContactSet.from_arrays([[1.0]], [1e-3], eps=0.5)
    sysm = ContactSystem.from_arrays(M=[[1.0]], Q=[[1e8]], C=[[1e308]], f0=[-1.0], contacts=cs)
    with pytest.raises(NsfemError, match="damping"):
        integrate(sysm, 0.01, "penalty", output_dt=1e-3)


def test_progress_lines_on_a_pipe():
    """On a pipe or a log file (not a terminal) progress is whole lines, never carriage returns."""
    stream = io.StringIO()
    p = Progress(2.0, True, delay=0.0, stream=stream, every=0.0)
    p(0.5, 3)
    p(1.0, 7)
    p.close()
    lines = stream.getvalue().splitlines(keepends=True)
    assert len(lines) == 2 and all(line.endswith("\n") and "\r" not in line for line in lines)
    assert lines[0].startswith("nsfem: progress: t = 0.5 of 2 s (25.0 %), events 3")
    silent = io.StringIO()
    Progress(2.0, None, delay=0.0, stream=silent, every=0.0)(1.0, 1)   # library default: only on a terminal
    assert silent.getvalue() == ""


def test_run_reports_progress_on_stderr_and_keeps_stdout_one_json(tmp_path, capsys, monkeypatch):
    """``nsfem run`` reports progress on stderr (here from the first phase: delay and interval 0),
    --json stays exactly one JSON object on stdout."""
    monkeypatch.setattr(Progress.__init__, "__defaults__", (None, 0.0, None, 0.0))
    code = cli.main(["run", "--json", "--out", str(tmp_path), "--set", "mesh.elements=20",
                     "--set", "simulation.t_end=0.01", "--set", "output.vtu_every=0", "--set", "output.plots=[]"])
    assert code == 0
    out, err = capsys.readouterr()
    assert json.loads(out)["completed"]
    assert "nsfem: progress: t = 0.01 of 0.01 s (100.0 %)" in err


def test_run_without_progress_stops_with_a_diagnosis_and_a_loadable_partial_result(tmp_path, capsys):
    """The shipped scene at 1e4 Hz (unstable: growth 6e4 1/s): a see-saw of impacts every
    4e-10 s, 2.7e9 events to t_end (the old loop: 8100 events, t = 3.5e-5 s in 120 s). The run
    stops in a second with one line on stderr, exit 2, and the results file up to there is valid
    and exports. (The motion grows by e^600 over 0.01 s: round-off decides whether the see-saw
    persists or all contacts close and the held structure overflows in 0.01 s; with
    output_dt = 1e-6 instead of 1e-4 it does the latter. Both end in a one-line error.)"""
    out_dir = tmp_path / "run"
    code = cli.main(["run", "--out", str(out_dir), "--set", "rotation.speed_hz=1e4", "--set", "simulation.t_end=1",
                     "--set", "simulation.output_dt=1e-4", "--set", "output.vtu_every=0", "--set", "output.plots=[]"])
    err = capsys.readouterr().err
    assert code == cli.EXIT_ERROR
    line = [ln for ln in err.splitlines() if ln.startswith("nsfem: error:")]
    assert len(line) == 1 and "delamination.0." in line[0]
    assert "no progress at t = " in line[0] or "the motion overflowed" in line[0]
    res, meta, extra = Result.load(out_dir / "result.npz")
    assert not res.completed and res.t.size >= 1 and np.all(np.isfinite(res.q))
    assert res.info["error"] in line[0]
    assert cli.main(["export", str(out_dir / "result.npz"), "--vtu", str(tmp_path / "vtu")]) == 0
