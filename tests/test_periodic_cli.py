"""nsfem periodic: the scene layer (nsfem.periodic.scene), its outputs and the command (issue 36).

References: a linear scene's periodic orbit is its harmonic (unbalance + gravity) steady state, solved here
directly from the system's matrices and by ``nsfem response``; a non-smooth orbit is checked by what it must
satisfy (the exact flow over one period returns to it)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from nsfem import cli, load_scene
from nsfem.periodic.scene import half_peak_to_peak, orbit_of_scene, parse_continuation

#: the linear scene: critical_speed (anisotropic damped bearings, unbalance and gravity in the inertial frame)
#: with a light mass-proportional damping, so that every mode (the undamped axial ones too) decays
LINEAR = ["mesh.elements=10", "reduction.modes=16", "damping.rayleigh=[1.0, 0.0]"]


def harmonic_state(system, t: float) -> tuple[np.ndarray, np.ndarray]:
    """(q, q') at t of the steady state q = a0 + ac cos(w t) + as sin(w t) of M q'' + C q' + Q q = f0 + fc
    cos(w t) + fs sin(w t): one dense solve of the 2n x 2n harmonic balance (exact for a linear system)."""
    M, C, Q, w = system.M, system.C, system.Q, system.omega
    a0 = np.linalg.solve(Q, system.f0)
    A = np.block([[Q - w**2 * M, w * C], [-w * C, Q - w**2 * M]])
    ac, as_ = np.split(np.linalg.solve(A, np.concatenate([system.fc, system.fs])), 2)
    c, s = math.cos(w * t), math.sin(w * t)
    return a0 + ac * c + as_ * s, w * (-ac * s + as_ * c)


@pytest.fixture(scope="module")
def linear_orbit():
    scene = load_scene("critical_speed", LINEAR)
    return scene, orbit_of_scene(scene, transient_periods=0)


def test_a_linear_orbit_is_the_harmonic_steady_state(linear_orbit):
    scene, so = linear_orbit
    o = so.orbit
    assert o.converged and o.residual <= 1e-9
    q, v = harmonic_state(so.system, o.t0)
    # Newton on a linear map lands on the fixed point in one step; what is left is the round-off of the
    # exponentials over one period and of the solves (condition ~1e3 x eps = 1e-13), far below 1e-8
    assert np.abs(o.q0 - q).max() <= 1e-8 * np.abs(q).max()
    assert np.abs(o.v0 - v).max() <= 1e-8 * np.abs(v).max()
    # damped (Rayleigh alpha = 1 1/s on top of the bearings): every multiplier inside the unit circle
    assert np.abs(o.multipliers).max() < 1.0 and o.stable and o.loss is None
    assert so.verdict() == "stable" and o.events_per_period == 0 and so.contact_sequence == []
    assert so.on_unit_circle() == 0


def test_an_undamped_orbit_is_marginally_stable():
    """Without damping (critical_speed's axial modes: a thrust spring, no damper, no Rayleigh damping) the
    multipliers of those modes are exp(i w T) exactly, |mu| = 1: the verdict says so."""
    scene = load_scene("critical_speed", ["mesh.elements=10", "reduction.modes=16"])
    so = orbit_of_scene(scene, transient_periods=0)
    assert so.orbit.stable and so.on_unit_circle() >= 2
    assert so.verdict().startswith("stable, marginally") and so.to_json()["on_unit_circle"] == so.on_unit_circle()


def test_a_linear_orbits_amplitudes_are_nsfem_responses(linear_orbit):
    """The probes' 1x amplitudes over the orbit equal the harmonic solve of ``nsfem response`` at the speed."""
    from nsfem.analysis.harmonic import amplitude_phase, harmonic_fit
    from nsfem.analysis.response import response_report
    from nsfem.fem.assemble import build_model
    from nsfem.reduce import scene_reduction

    scene, so = linear_orbit
    model = build_model(scene)
    speed = scene.rotation.speed_hz
    rep = response_report(scene, model, np.array([speed]), scene_reduction(scene.reduction, model))
    for k, s in enumerate(scene.sensors):
        want = rep["sensors"][s.name]["amplitude_m"][0]
        # the Fourier coefficient of the samples over the whole period is exact for a sinusoid: round-off only
        fit = harmonic_fit(so.t[:-1], so.signals[:-1, k], speed)
        assert amplitude_phase(fit)[0] == pytest.approx(want, rel=1e-8)
        # half the peak-to-peak, refined by a parabola through the extreme samples 2 pi / 256 apart: off by at
        # most h^4 / 24 = 1.5e-8 of the amplitude
        assert so.amplitudes[s.name] == pytest.approx(want, rel=2e-8)


def test_a_linear_subharmonic_is_the_harmonic_steady_state_too(linear_orbit):
    """--multiple 2 on a linear scene: the orbit of period 2 T is the unique steady state, of period T."""
    scene, so1 = linear_orbit
    so2 = orbit_of_scene(scene, multiple=2, transient_periods=0)
    assert so2.period_s == pytest.approx(2 * so1.period_s, rel=1e-15) and so2.orbit.converged
    q, v = harmonic_state(so2.system, 0.0)
    assert np.abs(so2.orbit.q0 - q).max() <= 1e-8 * np.abs(q).max()   # as for K = 1: round-off only
    # each multiplier is that of one forcing period squared (the same exponentials over twice the time); the
    # eigenvalues of the non-normal monodromy carry its round-off times its condition: 1e-8 of the largest
    mu1, mu2 = np.sort_complex(so1.orbit.multipliers ** 2), np.sort_complex(so2.orbit.multipliers)
    assert np.abs(mu1 - mu2).max() <= 1e-8 * np.abs(mu1).max()


def test_half_peak_to_peak_of_sampled_sinusoids():
    """The parabola refinement's error bound, h^4 / 24 of the amplitude (h: the sample spacing in phase),
    over phases of the samples; and a kink (an impact) keeps its sample."""
    for n in (64, 256):
        h = 2 * math.pi / n
        for phase in np.linspace(0.0, h, 7):
            y = 3.0 + 2.0 * np.cos(h * np.arange(n + 1) + phase)
            assert abs(half_peak_to_peak(y) - 2.0) <= 2.0 * h**4 / 24
    tri = np.abs(np.linspace(-1.0, 1.0, 101))   # a kink at the minimum, the maxima at the ends
    assert half_peak_to_peak(tri) == pytest.approx(0.5, abs=1e-15)


def test_the_crack_orbit_returns_to_itself_after_one_period():
    """The shipped crack scene (breathing crack: impacts, closing and opening each turn): the flow of the
    exact integrator over one period from the orbit's state returns to it."""
    from nsfem.integrate import integrate

    scene = load_scene("crack")
    so = orbit_of_scene(scene, section="start")
    o = so.orbit
    assert o.converged and o.residual <= 1e-9, o.residual
    assert o.t0 == 0.0   # from a transient of whole periods
    res = integrate(so.system, o.period_s, "exact", o.period_s / 8, o.q0, o.v0)
    x0, x1 = np.concatenate([o.q0, o.v0]), np.concatenate([res.q[:, -1], res.v[:, -1]])
    w = 2 * math.pi / o.period_s
    scale = np.concatenate([np.ones(so.system.n), np.full(so.system.n, 1 / w)])
    # the shooting's own tolerance 1e-9 on this norm; an independent run of the same exact flow repeats its
    # event times to ~1e-12 s: 1e-8 leaves room for that, not for a wrong orbit (residual 5e-3 at 30 periods)
    assert np.abs(scale * (x1 - x0)).max() <= 1e-8 * np.abs(scale * x0).max()
    # the crack breathes: it closes and opens each period, and every event is in the contact sequence
    kinds = {k for e in so.contact_sequence for k in e["kinds"]}
    assert {"close", "release"} <= kinds and len(so.contact_sequence) == o.events_per_period
    assert all(0.0 <= e["t_s"] <= o.period_s for e in so.contact_sequence)
    for k, s in enumerate(scene.sensors):
        assert so.amplitudes[s.name] == pytest.approx(half_peak_to_peak(so.signals[:, k]), rel=1e-15)


def test_the_crack_orbit_at_its_quiet_section_is_the_orbit_at_the_transients_end():
    """By default the shooting's section lies at the transient's last period's quiet phase (0 < t0 < T, no event
    within a quarter of the period's longest event-free stretch of it); it is the same orbit as at t0 = 0: the
    orbit shot at t0 = 0 flowed to t0 by an independent exact run is the quiet section's state, the amplitudes
    (section independent) and multipliers (invariant under moving the section) agree."""
    from nsfem.integrate import integrate

    scene = load_scene("crack")
    quiet, start = orbit_of_scene(scene), orbit_of_scene(scene, section="start")
    oq, os_ = quiet.orbit, start.orbit
    assert oq.converged and os_.converged
    assert 0.0 < oq.t0 < oq.period_s
    res = integrate(start.system, oq.t0, "exact", oq.t0, os_.q0, os_.v0)
    w = 2 * math.pi / oq.period_s
    x1 = np.concatenate([res.q[:, -1], res.v[:, -1] / w])
    xq = np.concatenate([oq.q0, oq.v0 / w])
    # both orbits converged to 1e-9 of their size; the independent run repeats event times to ~1e-12 s
    assert np.abs(x1 - xq).max() <= 1e-8 * np.abs(xq).max()
    # the amplitudes are half the peak-to-peak of N samples a period, at other phases at each section: a peak
    # between samples is missed by up to (2 pi / N)^2 / 8 of it (the 2x harmonic's: 4x that) -- the sampling's
    # error, far above the orbits' 1e-9
    n = len(start.t) - 1
    for name, a in start.amplitudes.items():
        assert quiet.amplitudes[name] == pytest.approx(a, rel=4 * (2 * math.pi / n) ** 2 / 8)
    mq = np.sort(np.abs(oq.multipliers))[::-1]
    ms = np.sort(np.abs(os_.multipliers))[::-1]
    # conjugate matrices: the same spectrum to the orbits' 1e-9 and the monodromy's round-off
    assert np.abs(mq[:6] - ms[:6]).max() <= 1e-6
    times = [e["t_s"] for e in quiet.contact_sequence]
    assert all(min(t, oq.period_s - t) > 0.0 for t in times)


@pytest.mark.parametrize("extra, word", [(["--start", "x.npz"], "--start"), (["--transient", "0"], "--transient 0"),
                                         (["--continue", "rotation.speed_hz=12:13"], "--continue")])
def test_section_is_refused_where_there_is_no_transient_to_choose_it_from(tmp_path, extra, word):
    import subprocess
    import sys

    r = subprocess.run([sys.executable, "-m", "nsfem", "periodic", "crack", "--section", "quiet", *extra, "--out",
                        str(tmp_path / "o")], capture_output=True, text=True, cwd=tmp_path)
    assert r.returncode == 2 and f"--section with {word}" in r.stderr and len(r.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "o").exists()


def test_the_crack_transient_ends_on_the_orbit():
    """The scene's own 8 s run ends on the orbit: its last period's amplitudes are the orbit's to the decay the
    scene documents (its 2x amplitude within 0.2 % of the steady one from 6 s on)."""
    from nsfem.simulate import run_scene, sensor_signals

    scene = load_scene("crack", ["output.vtu_every=0"])
    so = orbit_of_scene(scene)
    result, system = run_scene(scene)
    signals = sensor_signals(result, system)
    last = result.t >= result.t[-1] - so.period_s * (1 + 1e-9)
    for k, s in enumerate(scene.sensors):
        assert half_peak_to_peak(signals[last, k]) == pytest.approx(so.amplitudes[s.name], rel=2e-3)


def test_the_rub_orbit_is_the_stationary_full_annular_rub():
    """The shipped rub scene (rotating frame, no gravity: no time-dependent load there) has as orbit of one
    revolution its stationary state (LCP 28): the section state is it, at rest in the rotating frame, and the
    casing probes at the disk see the whirl circle of the disk's deflection; a note says why."""
    from nsfem.analysis.stationary import scene_stationary

    scene = load_scene("rub")
    so = orbit_of_scene(scene, transient_periods=10)   # shot from a transient: independent of LCP 28
    st = scene_stationary(scene)
    # both solve to round-off (the LCP's certificate, the shooting's residual 1e-9 relative at most)
    assert np.abs(so.orbit.q0 - st.q).max() <= 1e-9 * np.abs(st.q).max()
    assert np.abs(so.orbit.v0).max() <= 1e-9 * 2 * math.pi * scene.rotation.speed_hz * np.abs(st.q).max()
    assert so.orbit.converged and so.orbit.stable and "no time-dependent load" in so.notes[0]
    (disk,) = st.parts["disks"]
    for s in scene.sensors:   # a circle sampled 256 times a turn: its radius to h^4 / 24 = 1.5e-8
        assert s.frame == "inertial" and s.x == disk["x_m"]
        assert so.amplitudes[s.name] == pytest.approx(disk["magnitude_m"], rel=2e-8)


def test_a_scene_without_periodic_forcing_starts_from_its_stationary_state():
    """Without a time-dependent load in its frame (the rub in the rotating frame) the default start is the
    stationary state (LCP 28): the orbit is found with no Newton step (its residual at round-off, 1e-9 at most);
    an explicit --transient still runs the transient; a scene with periodic forcing (the crack: gravity turns in
    the rotating frame) starts from the transient."""
    so = orbit_of_scene(load_scene("rub"))
    assert so.orbit.converged and so.orbit.iterations == 0 and so.orbit.residual <= 1e-9
    assert "stationary" in so.to_json()["start"] and so.to_json()["transient_periods"] == 0
    assert "transient" in orbit_of_scene(load_scene("rub"), transient_periods=2).to_json()["start"]
    assert "transient" in orbit_of_scene(load_scene("crack")).to_json()["start"]


def test_a_start_from_a_run_and_from_an_orbit(tmp_path, capsys):
    """--start: a run's last state at t = 0.5 s (the section then at 0.5 s modulo T) and the orbit.npz of the
    orbit found from it, which is the orbit already (no Newton step)."""
    run_dir, p1, p2 = tmp_path / "run", tmp_path / "p1", tmp_path / "p2"
    quiet = ["--set", "output.vtu_every=0", "--set", "output.plots=[]"]
    assert cli.main(["run", "crack", *quiet, "--set", "simulation.t_end=0.5", "--out", str(run_dir)]) == 0
    capsys.readouterr()
    assert cli.main(["periodic", "crack", *quiet, "--start", str(run_dir / "result.npz"), "--out", str(p1),
                     "--json"]) == 0
    first = json.loads(capsys.readouterr().out)
    assert first["converged"] and first["transient_periods"] == 0 and "result.npz" in first["start"]
    assert first["t0_s"] == pytest.approx(math.fmod(0.5, 1 / 12.4), abs=1e-15)
    assert cli.main(["periodic", "crack", *quiet, "--start", str(p1 / "orbit.npz"), "--out", str(p2), "--json"]) == 0
    second = json.loads(capsys.readouterr().out)
    assert second["converged"] and second["iterations"] == 0 and second["t0_s"] == first["t0_s"]
    # the same orbit: its amplitudes to the shooting's tolerance (1e-9 relative residual)
    for name, a in first["amplitudes"].items():
        assert second["amplitudes"][name] == pytest.approx(a, rel=1e-8)


def _spy_figures(monkeypatch) -> dict:
    from matplotlib.figure import Figure

    seen, real = {}, Figure.savefig

    def spy(self, fname, *args, **kwargs):
        seen[str(fname).split("/")[-1].lstrip(".").split(".png")[0] + ".png"] = self
        return real(self, fname, *args, **kwargs)

    monkeypatch.setattr(Figure, "savefig", spy)
    return seen


def test_the_commands_outputs_agree(tmp_path, monkeypatch, capsys):
    """periodic.json = the printed JSON = orbit.npz's meta and arrays = the figures' data; the VTU series
    covers one period."""
    figs = _spy_figures(monkeypatch)
    out = tmp_path / "p"
    assert cli.main(["periodic", "critical_speed", *sum((["--set", s] for s in LINEAR), []),
                     "--transient", "0", "--out", str(out), "--json"]) == 0
    printed = json.loads(capsys.readouterr().out)
    saved = json.loads((out / "periodic.json").read_text())
    assert printed == saved
    for key in ("period_s", "converged", "residual", "multipliers", "stable", "events_per_period", "amplitudes"):
        assert key in saved   # design.md section 9
    assert saved["period_s"] == pytest.approx(1 / 26.0, rel=1e-15) and saved["converged"] and saved["stable"]
    with np.load(out / "orbit.npz") as z:
        meta = json.loads(str(z["meta"]))
        assert meta["amplitudes"] == saved["amplitudes"] and meta["multipliers"] == saved["multipliers"]
        mu = z["multipliers"]
        assert [[m.real, m.imag] for m in mu] == saved["multipliers"]
        names = list(z["sensors"])
        for k, name in enumerate(names):
            assert half_peak_to_peak(z["signals"][:, k]) == saved["amplitudes"][name]
        assert z["t"][0] == z["t0"] and z["t"][-1] == pytest.approx(z["t0"] + z["period_s"], rel=1e-14)
        line = figs["orbit.png"].axes[0].lines[0]   # y against z of the disk's probes, in um
        assert np.array_equal(line.get_xdata(), 1e6 * z["signals"][:, names.index("disk_y")])
        assert np.array_equal(line.get_ydata(), 1e6 * z["signals"][:, names.index("disk_z")])
        inside, outside = figs["floquet.png"].axes[0].lines[1:3]   # after the unit circle: dots, crosses
        drawn = np.concatenate([np.asarray(ln.get_xdata()) + 1j * np.asarray(ln.get_ydata()) for ln in (inside, outside)])
        assert len(outside.get_xdata()) == 0
        assert sorted(drawn, key=lambda c: (c.real, c.imag)) == sorted(mu, key=lambda c: (c.real, c.imag))
    pvd = (out / "nsfem.pvd").read_text()
    times = [float(x.split('"')[1]) for x in pvd.split("timestep=")[1:]]
    assert times[0] == 0.0 and times[-1] == pytest.approx(1 / 26.0, rel=1e-12)


def test_continue_is_parsed(tmp_path):
    """(The branch itself: tests/test_periodic_continue.py.)"""
    from tests.test_fuzz import check_invocation

    assert parse_continuation("stator.0.friction=0.3:0.1") == ("stator.0.friction", 0.3, 0.1)
    code, _, err = check_invocation(["periodic", "crack", "--continue", "rotation.speed_hz=10:10"], tmp_path)
    assert code == 2 and "same value" in err and "rotation.speed_hz" in err


def test_the_help_says_the_defaults_and_ranges_the_scene_layer_uses(capsys):
    """cli.py writes them out (it does not import nsfem.periodic to build its parser): they must agree."""
    from nsfem.periodic import scene as ps

    with pytest.raises(SystemExit):
        cli.main(["periodic", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert f"default {ps.TRANSIENT_PERIODS};" in text
    assert f"from {ps.TOL_RANGE[0]:g} to {ps.TOL_RANGE[1]:g}" in text


def test_an_interrupted_transient_keeps_the_folder_as_it_was(tmp_path, monkeypatch, capsys):
    """Ctrl-C or SIGTERM during the transient (the integrator then returns its run so far, completed = False):
    no shooting from a state at the wrong phase; exit 130, and the earlier orbit's files stay as they were."""
    import nsfem.simulate as simulate

    out = tmp_path / "p"
    argv = ["periodic", "critical_speed", *sum((["--set", s] for s in LINEAR), []), "--set", "output.vtu_every=0",
            "--out", str(out)]
    assert cli.main([*argv, "--transient", "0"]) == 0
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    real = simulate.integrate_prepared

    def interrupted(*args, **kwargs):
        result, system = real(*args, **kwargs)
        result.completed = False
        return result, system

    monkeypatch.setattr(simulate, "integrate_prepared", interrupted)
    capsys.readouterr()
    assert cli.main([*argv, "--transient", "3"]) == 130
    assert "interrupted" in capsys.readouterr().err
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before


def test_half_peak_to_peak_does_not_guess_the_repeated_end():
    """review2: an orbit's outputs run from t0 to t0 + T, so the last sample is the first again up to the
    shooting's residual, not bitwise; and an open sampling (no repeated end) can have equal ends when the
    signal is symmetric about the section. Guessing from y[-1] == y[0] took a wrong neighbour for the parabola
    at a peak next to the section: 3.8e-5 and 7.5e-5 of the amplitude off (2500 times the bound h^4 / 24 of a
    sampled cosine). Both samplings must meet that bound whatever round-off the end carries."""
    n = 256
    h = 2 * math.pi / n
    for phase in (0.0, 0.3 * h, -0.3 * h, 0.5 * h):
        closed = 2.0 * np.cos(h * np.arange(n + 1) + phase)
        closed[-1] = closed[0] + 1e-14   # the period's end: the start again, up to a residual 5e-15 relative
        assert abs(half_peak_to_peak(closed) - 2.0) <= 2.0 * h**4 / 24, phase
        assert abs(half_peak_to_peak(closed[:-1], closed=False) - 2.0) <= 2.0 * h**4 / 24, phase


#: critical_speed beside a rigid stop at the disk probes' x, 20 um along +y, struck once a period
STOP = [*LINEAR, "obstacle.0.x=0.5", "obstacle.0.normal=+y", "obstacle.0.clearance=2e-5",
        "obstacle.0.restitution=0.5", "output.vtu_every=0"]


def test_an_impact_peak_is_the_stop_not_the_sample_before_it():
    """review2: the probe at the stop reads y = 20 um at the impact (the gap, 20 um - y, is zero there): its
    largest value over the period. Sampled 256 times a period the kink fell between samples, 0.2 um short of it
    (1 % of the amplitude, the branch's disk_y curve jagged point to point). The amplitude is half of (the stop's
    20 um - the smallest value): the event search closes the gap to round-off (1e-12 m of 2e-5) and the smooth
    minimum is refined to 1.5e-8 of the amplitude (3e-13 m): 1e-11 m bounds both."""
    from nsfem.periodic.scene import _extreme

    for speed in (21.0, 20.4):
        so = orbit_of_scene(load_scene("critical_speed", [*STOP, f"rotation.speed_hz={speed}"]))
        assert so.orbit.converged and sum(e["impact"] for e in so.contact_sequence) == 1
        y = so.signals[:-1, 0]
        assert y.max() < 2e-5 - 1e-9   # the samples miss the kink: the case this test is about
        low = -_extreme(y, -1.0)
        assert abs(so.amplitudes["disk_y"] - 0.5 * (2e-5 - low)) <= 1e-11, (speed, so.amplitudes["disk_y"])


def test_a_shooting_that_did_not_converge_gives_no_stability():
    """review2: a shooting that did not converge has no orbit, so no verdict (the docs, and verdict() says so),
    but periodic.json (and a periodic sweep's row) said "stable": true/false and a "loss" of its last iterate's
    multipliers. They are null; converged is false and the warning says why."""
    from nsfem.periodic.shooting import periodic_orbit

    def one_step(*args, **kwargs):
        return periodic_orbit(*args, **{**kwargs, "max_iter": 1, "attempts": 1})

    warned = []
    so = orbit_of_scene(load_scene("crack", ["output.vtu_every=0"]), transient_periods=0, shoot=one_step,
                        warn=warned.append)
    assert not so.orbit.converged   # one Newton step from the initial state: the case this test is about
    j = so.to_json()
    assert j["converged"] is False and j["stable"] is None and j["loss"] is None
    assert so.verdict().startswith("none") and any("did not converge" in w for w in warned)


def test_event_times_are_counted_from_the_section(tmp_path):
    """review2: contact_sequence's t_s is the time after the section t0. With t0 = 0 (a transient of whole
    periods) a time from the clock's zero passes as one: nothing checked it. The crack's orbit started from its
    own state 96/256 of a period on (an orbit.npz of that section) has its events at the first orbit's times less
    that shift, modulo the period; the event search places an event to ~1e-13 s (the shooting's two runs differ
    by that), 1e-9 s is far above it and far below the 30 ms shift."""
    scene = load_scene("crack", ["output.vtu_every=0"])
    so = orbit_of_scene(scene)
    T, k, res = so.period_s, 96, so.orbit.result
    np.savez(tmp_path / "orbit.npz", q0=res.q[:, k], v0=res.v[:, k], t0=np.array(so.t[k]))
    moved = orbit_of_scene(scene, start=tmp_path / "orbit.npz")
    assert moved.orbit.converged and moved.orbit.t0 == pytest.approx(so.t[k], abs=1e-15)
    expected = sorted((so.orbit.t0 + e["t_s"] - so.t[k]) % T for e in so.contact_sequence)   # so.t: the clock's
    got = sorted(e["t_s"] for e in moved.contact_sequence)
    assert all(0.0 <= t <= T for t in got)
    assert np.abs(np.array(got) - np.array(expected)).max() <= 1e-9
    assert moved.to_json()["t0_s"] == pytest.approx(so.t[k], abs=1e-15)


def test_ctrl_c_during_the_shooting_interrupts_it(monkeypatch):
    """review2: Ctrl-C (SIGINT) inside one of the shooting's flows ended that flow early (the integrator's clean
    stop, completed = False), which the shooting took for a failed Newton step and went on: the command then wrote
    a 'not converged' orbit and exited 0 (retainer_drop with polygon rings, SIGINT at 12 s: 23 instead of 35
    iterations, exit 0). The interrupt ends the shooting: KeyboardInterrupt (the command's exit 130). The signal is
    raised at the 5th event of the shooting's flows (inside the integrator's loop, where it was swallowed)."""
    import signal

    from nsfem.integrate import event_driven
    from nsfem.periodic.shooting import periodic_orbit

    real, calls = event_driven.resolve, []

    def resolve(*args, **kwargs):
        calls.append(1)
        if len(calls) == 5:
            signal.raise_signal(signal.SIGINT)
        return real(*args, **kwargs)

    def shoot(*args, **kwargs):
        monkeypatch.setattr(event_driven, "resolve", resolve)
        return periodic_orbit(*args, **kwargs)

    scene = load_scene("crack", ["output.vtu_every=0"])
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)   # Ctrl-C's, even where started ignored
    try:
        with pytest.raises(KeyboardInterrupt):
            orbit_of_scene(scene, transient_periods=0, shoot=shoot)
    finally:
        signal.signal(signal.SIGINT, previous)
    assert len(calls) == 5   # stopped there, not after the shooting's other flows
