"""The files of ``nsfem periodic`` (besides periodic.json): orbit.npz, orbit.png, floquet.png and the VTU
series of one period, each written atomically.

orbit.npz is readable with numpy alone::

    import json, numpy as np
    o = np.load("out/periodic/orbit.npz")
    o["t"], o["q"], o["gap"]            # (K,) times over one period from the section t0 [s]; (n, K); (m, K)
    o["q0"], o["v0"], o["t0"]           # the state at the section (the shooting's unknowns) and its time
    o["monodromy"], o["multipliers"]    # (d, d) and complex (d,), largest modulus first
    o["signals"], o["sensors"]          # (K, sensors) [m] and their names
    meta = json.loads(str(o["meta"]))   # the periodic.json keys
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from ..atomic import write_atomic
from ..jsonio import dumps


def save_orbit(path: str | Path, so, meta: dict) -> Path:
    """orbit.npz of a :class:`~nsfem.periodic.scene.SceneOrbit` (``meta``: its JSON keys, stored as ``meta``)."""
    o, res = so.orbit, so.orbit.result
    arrays = dict(t=so.t, q=res.q, v=res.v, gap=res.gap, normal_force=res.normal_force,
                  tangential_force=res.tangential_force, state=res.state, q0=np.asarray(o.q0, dtype=float),
                  v0=np.asarray(o.v0, dtype=float), t0=np.array(float(o.t0)), period_s=np.array(float(o.period_s)),
                  monodromy=np.asarray(o.monodromy, dtype=float),
                  multipliers=np.asarray(o.multipliers, dtype=complex), signals=so.signals,
                  sensors=np.array([s.name for s in so.sensors], dtype=str),
                  contacts=np.array(list(so.system.model_contacts.labels), dtype=str), meta=np.array(dumps(meta)))

    def write(tmp):
        with open(tmp, "wb") as fh:   # a file object: numpy would append .npz to a name
            np.savez_compressed(fh, **arrays)

    return write_atomic(path, write)


def write_orbit(so, scene, out_dir: str | Path, meta: dict | None = None) -> list[Path]:
    """orbit.npz, the figures (unless the scene's output.plots is empty) and the VTU series of one period
    (unless output.vtu_every is 0) of ``so`` into ``out_dir``; returns the paths written."""
    from ..plot.periodic import floquet_plot, orbit_plot
    from ..plot.sensors import stator_rings
    from .scene import vtu_every

    out = Path(out_dir)
    written = [save_orbit(out / "orbit.npz", so, so.to_json() if meta is None else meta)]
    res = so.orbit.result
    if scene.output.plots:
        written.append(orbit_plot(out / "orbit.png", so.t, so.signals, so.sensors, res.gap, res.normal_force,
                                  list(so.system.model_contacts.labels), stator_rings(so.system), scene.title))
        written.append(floquet_plot(out / "floquet.png", so.orbit.multipliers, so.verdict(), scene.title))
    if scene.output.vtu_every and so.t.size > 1:
        from ..export.vtu import write_series

        timed = replace(res, t=so.t)   # the forcing's clock: an inertial series turns by Omega t + phase
        written.append(write_series(timed, so.system, out, every=vtu_every(so.t.size - 1, so.multiple)))
    return written


def save_branch(path: str | Path, sb, meta: dict) -> Path:
    """branch.npz of a :class:`~nsfem.periodic.scene_branch.SceneBranch`: per point (the branch's, then each
    doubled branch's) ``value``, ``q0``/``v0`` (points, n) the section states, ``period_s``, ``multiple``,
    ``stable``, ``largest_multiplier``, ``amplitudes`` (points, sensors) [m], ``branch`` (0: the branch, k: the
    k-th doubled one), ``t0_s`` each point's section time [s] (q0, v0 are the state there; it moves off events
    that drift onto it) and ``t0`` the first point's; ``sensors`` their names; ``meta`` the branch.json keys."""
    rows = [(0, p) for p in sb.points] + [(k + 1, p) for k, d in enumerate(sb.doubled) for p in d["points"]]
    names = [s.name for s in sb.sensors]
    n = int(sb.start.system.n)

    def column(get, dtype=float):
        return np.array([get(p) for _, p in rows], dtype=dtype)

    arrays = dict(value=column(lambda p: p["value"]),
                  q0=np.array([p["q0"] for _, p in rows], dtype=float).reshape(len(rows), n),
                  v0=np.array([p["v0"] for _, p in rows], dtype=float).reshape(len(rows), n),
                  period_s=column(lambda p: p["period_s"]), multiple=column(lambda p: p["multiple"], int),
                  stable=column(lambda p: p["stable"], bool), converged=column(lambda p: p["converged"], bool),
                  largest_multiplier=column(lambda p: p["largest_multiplier"]),
                  amplitudes=np.array([[p["amplitudes"].get(s, np.nan) for s in names] for _, p in rows],
                                      dtype=float).reshape(len(rows), len(names)),
                  branch=np.array([k for k, _ in rows], dtype=int), sensors=np.array(names, dtype=str),
                  t0=np.array(float(sb.start.orbit.t0)),
                  t0_s=column(lambda p: p.get("t0_s", sb.start.orbit.t0)), meta=np.array(dumps(meta)))

    def write(tmp):
        with open(tmp, "wb") as fh:
            np.savez_compressed(fh, **arrays)

    return write_atomic(path, write)
