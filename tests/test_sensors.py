"""Sensors: what a probe reads between nodes and in either frame, and what `run` writes."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest
import scipy.sparse as sp

from nsfem import build_model, cli, load_scene
from nsfem.errors import SceneError
from nsfem.sensors import Sensor, hermite_row, read


def test_hermite_row_reads_a_cubic_exactly_between_nodes():
    model = build_model(load_scene(None, ["delamination=[]", "obstacle=[]", "mesh.elements=7"]))
    space = model.spaces["intact_0"]
    q = np.zeros(model.n_full)
    f = lambda x: 0.3 - 1.7 * x + 2.9 * x**2 - 4.1 * x**3     # noqa: E731  a cubic: Hermite holds it exactly
    df = lambda x: -1.7 + 5.8 * x - 12.3 * x**2               # noqa: E731
    nd = space.bending.nodal_dofs
    for i, x in enumerate(space.x):
        q[space.dofs["W"][nd[0, i]]] = f(x)
        q[space.dofs["W"][nd[1, i]]] = df(x)
    for x in (0.0, 0.0371, 0.5, 0.77777, 1.0):
        # round-off of four products of O(1) terms
        assert float((hermite_row(model, "intact_0", "W", x) @ q)[0]) == pytest.approx(f(x), abs=1e-14)


def test_a_probe_fixed_in_space_sees_a_rotating_frame_deflection_turn():
    """A constant deflection r at angle a in the rotating frame passes an inertial probe as
    r cos(Omega t + phi + a) along y and r sin(...) along z; a rotating probe sees it still."""
    model = build_model(load_scene(None, ["delamination=[]", "obstacle=[]", "mesh.elements=8"]))
    x, r, a, speed, phi = 0.375, 2e-5, 0.7, 13.0, 25.0   # x on a node (8 elements)
    q = np.zeros(model.n_full)
    q[model.dof("intact_0", "V", x)] = r * math.cos(a)
    q[model.dof("intact_0", "W", x)] = r * math.sin(a)
    t = np.linspace(0.0, 0.2, 41)
    Q = np.repeat(q[:, None], t.size, axis=1)
    sensors = [Sensor("y", x, "+y", "inertial", "intact_0"), Sensor("z", x, "-z", "inertial", "intact_0"),
               Sensor("zr", x, "+z", "rotating", "intact_0")]
    got = read(sensors, model, sp.identity(model.n_full, format="csr"), t, Q, "rotating", speed, phi)
    theta = 2 * math.pi * speed * t + math.radians(phi) + a
    # the angle-sum identity in floats: a few ulps of r (1e-13 r leaves room for the angle's round-off)
    np.testing.assert_allclose(got[:, 0], r * np.cos(theta), rtol=0, atol=1e-13 * r)
    np.testing.assert_allclose(got[:, 1], -r * np.sin(theta), rtol=0, atol=1e-13 * r)
    np.testing.assert_allclose(got[:, 2], r * math.sin(a), rtol=1e-14)
    # and back: the inertial signals read from the rotating probe's frame give the deflection again
    qi = np.zeros((model.n_full, t.size))
    qi[model.dof("intact_0", "V", x)] = r * np.cos(theta)
    qi[model.dof("intact_0", "W", x)] = r * np.sin(theta)
    back = read(sensors[2:], model, sp.identity(model.n_full, format="csr"), t, qi, "inertial", speed, phi)
    np.testing.assert_allclose(back[:, 0], r * math.sin(a), rtol=1e-12)


def test_run_writes_sensors_csv(tmp_path, capsys):
    out = tmp_path / "out"
    code = cli.main(["run", "--set", "simulation.t_end=0.02", "--set", "output.vtu_every=0",
                     "--set", 'sensor=[{name="mid",x=0.05,direction="+z"},{name="up",x=0.5,layer="upper"}]',
                     "--set", "output.plots=[]", "--out", str(out), "--json"])
    assert code == 0
    payload = json.loads(capsys.readouterr().out)
    data = np.genfromtxt(payload["sensors"], delimiter=",", names=True)
    assert data.dtype.names == ("t", "mid", "up")
    r = np.load(out / "result.npz")
    np.testing.assert_array_equal(data["t"], r["t"])
    # the upper layer's z at x = 0.5 in the inertial frame, from the saved coordinates by hand
    model = build_model(load_scene(None))
    row = hermite_row(model, "delamination_0_upper", "W", 0.5) @ r["basis"]
    v = np.ravel(hermite_row(model, "delamination_0_upper", "V", 0.5) @ r["basis"] @ r["q"])
    w = np.ravel(row @ r["q"])
    theta = 2 * math.pi * 21.0 * r["t"]
    np.testing.assert_allclose(data["up"], np.sin(theta) * v + np.cos(theta) * w, rtol=1e-12, atol=1e-22)


def test_sensor_errors():
    with pytest.raises(SceneError, match="sensor.0.layer: x=0.5 lies in a delamination"):
        load_scene(None, ["sensor.0.x=0.5"])
    with pytest.raises(SceneError, match="sensor.1.name: 'a' is taken"):
        load_scene(None, ['sensor.0.name="a"', "sensor.0.x=0.05", 'sensor.1.name="a"', "sensor.1.x=0.05"])
    with pytest.raises(SceneError, match="sensor.0.x: x=3.0 lies outside"):
        load_scene(None, ["sensor.0.x=3.0"])


# --- issue 34: sensor plots (orbits with the clearance circle, envelope of long records) ---
def test_orbit_panel_draws_the_stator_clearance_circle_at_its_x(tmp_path, monkeypatch):
    """rub: one rigid ring (64 facets, clearance 0.1 mm) at x = 0.4 with the probe pair there: its orbit
    panel carries the circle of radius 100 um about the bearing axis, labelled y horizontal, z vertical."""
    from matplotlib.figure import Figure

    from nsfem.plot.sensors import sensors_plot, stator_rings
    from nsfem.simulate import run_scene, sensor_signals

    scene = load_scene("rub", ["simulation.t_end=0.05", "mesh.elements=8"])
    result, system = run_scene(scene)
    rings = stator_rings(system)
    assert rings == [(0.4, 1e-4)]
    assert stator_rings(run_scene(load_scene(None, ["simulation.t_end=0.001", "mesh.elements=16"]))[1]) == []
    figs = []
    real = Figure.savefig
    monkeypatch.setattr(Figure, "savefig", lambda self, *a, **k: (figs.append(self), real(self, *a, **k))[1])
    sensors_plot(tmp_path / "sensors.png", result.t, sensor_signals(result, system), scene.sensors,
                 scene.rotation.speed_hz, scene.title, rings)
    (fig,) = figs
    (orbit,) = [ax for ax in fig.axes if ax.get_title().startswith("orbit")]
    assert orbit.get_xlabel() == "y, horizontal [µm]" and orbit.get_ylabel() == "z, vertical (up) [µm]"
    circles = [ln for ln in orbit.lines if ln.get_linestyle() == "--"]
    (circle,) = circles
    r = np.hypot(circle.get_xdata(), circle.get_ydata())
    np.testing.assert_allclose(r, 100.0, rtol=1e-14)     # cos^2 + sin^2 = 1 to a few ulps
    # a probe pair elsewhere gets no circle
    fig.clear()
    figs.clear()
    moved = [dataclasses.replace(s, x=0.2) for s in scene.sensors]
    sensors_plot(tmp_path / "sensors.png", result.t, sensor_signals(result, system), moved, 22.4, "", rings)
    (orbit,) = [ax for ax in figs[0].axes if ax.get_title().startswith("orbit")]
    assert [ln for ln in orbit.lines if ln.get_linestyle() == "--"] == []
