"""What the run plots read from a Result: modal coordinates, PSDs, contact groups, closed intervals,
measurement points (shared by :mod:`nsfem.plot.phase`, :mod:`~nsfem.plot.gap`, :mod:`~nsfem.plot.psd`,
:mod:`~nsfem.plot.forces`)."""

from __future__ import annotations

import math

import numpy as np

from ..errors import NsfemError

FIGSIZE = (6.4, 4.8)


class NoPlotData(NsfemError):
    """The run holds nothing this plot could show; the message says why."""


# --------------------------------------------------------------------------- helpers
def _dense(A) -> np.ndarray:
    return np.asarray(A.toarray() if hasattr(A, "toarray") else A, dtype=float)


def _model_and_T(system):
    """(model, T with q_full = T q) from ``system.info``, or (None, None)."""
    info = getattr(system, "info", None) or {}
    model, red = info.get("model"), info.get("reduction")
    if model is None:
        return None, None
    return model, (red.T if red is not None else model.T)


def _speed_hz(result, system) -> float:
    s = result.info.get("speed_hz")
    if s is None:
        s = getattr(system, "omega", 0.0) / (2.0 * math.pi)
    return float(s or 0.0)


def _window(t: np.ndarray, steady_from: float | None) -> np.ndarray:
    """Boolean mask of the samples at t >= steady_from (default: the last half of the run)."""
    if t.size == 0:
        return np.zeros(0, bool)
    if steady_from is None:
        steady_from = t[0] + 0.5 * (t[-1] - t[0])
    return t >= steady_from


def modal_basis(system) -> tuple[np.ndarray, np.ndarray]:
    """(frequencies [Hz], Phi): the mass-normalized modes of the open, non-rotating system.

    Eigenvectors of K0 phi = w^2 M phi in the system's (reduced) coordinates, ascending,
    Phi^T M Phi = I, so q = Phi eta and eta = Phi^T M q. K0 is the non-rotating elastic
    stiffness T^T K_full T (the paper's "eigenshapes of the non-rotating model") when the
    system carries its finite-element model; otherwise the symmetric part of ``system.Q``
    (which at a nonzero speed also holds the centrifugal terms).
    """
    import scipy.linalg as sla

    M = np.asarray(system.M, dtype=float)
    model, T = _model_and_T(system)
    if model is not None:
        K = _dense(T.T @ (model.K_full @ T))
    else:
        Q = np.asarray(system.Q, dtype=float)
        K = 0.5 * (Q + Q.T)
    K = 0.5 * (K + K.T)
    lam, Phi = sla.eigh(K, M)
    return np.sqrt(np.clip(lam, 0.0, None)) / (2.0 * math.pi), Phi


def modal_coordinates(result, system) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(frequencies [Hz], eta, eta') of every mode of :func:`modal_basis`: eta = Phi^T M q."""
    f, Phi = modal_basis(system)
    P = Phi.T @ np.asarray(system.M, dtype=float)
    return f, P @ result.q, P @ result.v


def welch_psd(signal, dt: float, nperseg: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(f [Hz], one-sided PSD [unit^2/Hz]) of a uniformly sampled signal (Hann, 50 % overlap,
    mean removed); default segments of half the record (three averages)."""
    from ..spectrum import welch

    x = np.asarray(signal, dtype=float)
    n = x.size
    if nperseg is None:
        nperseg = n if n < 32 else max(32, n // 2)
    return welch(x, dt, min(nperseg, n))


def _uniform(t: np.ndarray, y: np.ndarray) -> tuple[float, np.ndarray]:
    """(dt, y on a uniform grid): output times are uniform except for round-off; else interpolate."""
    d = np.diff(t)
    dt = float(np.median(d))
    if np.allclose(d, dt, rtol=1e-6, atol=0.0):
        return dt, y
    grid = np.arange(t[0], t[-1] + 0.5 * dt, dt)
    return dt, np.interp(grid, t, y)


def delamination_middles(system) -> list[dict]:
    """Per contact part (:func:`nsfem.contact.tally.system_parts`: a delamination, stator ring, crack or
    stop): its contacts and the one nearest its midspan.

    Each entry: ``name`` ("delamination.0", "crack.0", "stator.1", "obstacle.1", ...), ``kind``
    ("delamination", "ring", "crack" or "stop"), ``part`` (the :class:`~nsfem.contact.tally.Part`),
    ``indices`` (contact rows), ``middle`` (the row nearest the middle), ``x`` (its position [m]) and
    ``span`` (start, end) [m]: a delamination's is its layers' length, a ring's, crack's or stop's its
    position; without a model, that of the contacts' positions.
    """
    from ..contact.tally import system_parts

    cs = system.model_contacts
    if cs.m == 0:
        return []
    xs = np.asarray(cs.x, dtype=float)
    model, _ = _model_and_T(system)
    contacts = model.stack.contacts if model is not None and len(model.stack.contacts) == cs.m else None
    out = []
    for part in system_parts(system):
        idx = np.asarray(part.rows)
        if contacts is not None and part.kind == "delamination":
            seg = model.stack.segment(contacts[idx[0]].segments[0])
            span = (seg.start, seg.end)
        else:
            gx = xs[idx]
            span = (float(np.nanmin(gx)), float(np.nanmax(gx))) if np.isfinite(gx).any() else (np.nan, np.nan)
        mid = 0.5 * (span[0] + span[1])
        if np.isfinite(mid) and np.isfinite(xs[idx]).all():
            k = int(idx[np.argmin(np.abs(xs[idx] - mid))])
        else:
            k = int(idx[len(idx) // 2])
        out.append({"name": part.name, "kind": part.kind, "part": part, "indices": [int(i) for i in idx],
                    "middle": k, "x": float(xs[k]), "span": tuple(float(v) for v in span)})
    return out


def closed_intervals(result, k, every: bool = True) -> list[tuple[float, float]]:
    """[(t_close, t_release)] of contact row k: from the events when the integrator records
    them (exact), else from the sampled states. ``k`` may be a list of rows (a crack's front
    ends): closed when all of them are (``every``; else when any is: the crack at least partly
    closed). See :func:`nsfem.contact.tally.closed_spans`."""
    from ..contact.tally import closed_spans

    return closed_spans(result.t, result.state, result.events, k, every=every,
                        index=result.info.get("contact_index"))


def measurement_point(model, x: float | None = None, field: str = "W") -> dict:
    """The mesh node where :func:`psd_plot` reads the displacement.

    Default: a quarter span from the left end if that lies in an undamaged segment (one
    that joins no interface contact), else the middle of the undamaged segment nearest to
    it; segment ends (supports, junctions) are avoided. A given ``x`` is snapped to the
    nearest node of a segment containing it (undamaged ones first). Returns ``segment``,
    ``x``, ``dof`` (full index) and ``undamaged`` (bool).
    """
    stack = model.stack
    damaged = {s for c in stack.contacts if c.kind == "interface" for s in c.segments}
    segs = list(stack.segments)
    intact = [s for s in segs if s.name not in damaged]
    x0, x1 = min(s.start for s in segs), max(s.end for s in segs)

    def nearest(seg, target, interior=True):
        nodes = np.asarray(model.spaces[seg.name].x, dtype=float)
        if interior and nodes.size > 2:
            nodes = nodes[1:-1]
        return float(nodes[np.argmin(np.abs(nodes - target))])

    if x is not None:
        x = float(x)
        hit = [s for s in intact if s.start <= x <= s.end] or [s for s in segs if s.start <= x <= s.end]
        if not hit:
            raise NsfemError(f"psd: x={x} lies outside the shaft [{x0}, {x1}]")
        seg, xn = hit[0], nearest(hit[0], x, interior=False)
    else:
        target = x0 + 0.25 * (x1 - x0)
        pool = intact or segs
        inside = [s for s in pool if s.start <= target <= s.end]
        if inside:
            seg = inside[0]
            xn = nearest(seg, target)
        else:
            seg = min(pool, key=lambda s: min(abs(s.start - target), abs(s.end - target)))
            xn = nearest(seg, 0.5 * (seg.start + seg.end))
    return {"segment": seg.name, "x": xn, "dof": model.dof(seg.name, field, xn),
            "undamaged": seg.name not in damaged}


# --------------------------------------------------------------------------- plots
def hermite_refine(t: np.ndarray, x: np.ndarray, dx: np.ndarray, f_hz: float, kicks=(),
                   per_period: int = 48) -> tuple[np.ndarray, np.ndarray]:
    """(x, x') drawn between samples as the cubic Hermite interpolant of the values and rates there,
    about ``per_period`` points per period of ``f_hz`` (an 83 Hz mode sampled every 1 ms is a 12-gon; 48 sag by 2e-3;
    the interpolant is within (w h)^4 / 384 of a harmonic, 2e-4 there, its slope within (w h)^3 / 72).
    Intervals holding an impact (a jump in x') keep their straight chord."""
    t, x, dx = (np.asarray(a, dtype=float) for a in (t, x, dx))
    if t.size < 2 or not f_hz > 0:
        return x, dx
    h = np.diff(t)
    n = np.clip(np.ceil(h * f_hz * per_period).astype(int), 1, 64)
    if np.all(n == 1):
        return x, dx
    kicks = np.sort(np.asarray(kicks, dtype=float))
    # an interval (t_i, t_i+1] holding an impact keeps its chord: one point, its end
    hit = np.searchsorted(kicks, t[1:], side="right") > np.searchsorted(kicks, t[:-1], side="right")
    n[hit] = 1
    i = np.repeat(np.arange(t.size - 1), n)             # the interval of each drawn point
    s = (np.arange(i.size) - np.repeat(np.cumsum(n) - n, n) + 1) / n[i]    # k / n_i, k = 1..n_i
    h00, h10, h01, h11 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s, -2 * s**3 + 3 * s**2, s**3 - s**2
    d00, d10, d01, d11 = 6 * s**2 - 6 * s, 3 * s**2 - 4 * s + 1, -6 * s**2 + 6 * s, 3 * s**2 - 2 * s
    hi = h[i]
    xi = h00 * x[i] + h10 * hi * dx[i] + h01 * x[i + 1] + h11 * hi * dx[i + 1]
    dxi = (d00 * x[i] + d01 * x[i + 1]) / hi + d10 * dx[i] + d11 * dx[i + 1]
    end = (n == 1)[i]                                   # a single point is the interval's end sample itself
    xi[end], dxi[end] = x[i[end] + 1], dx[i[end] + 1]
    return np.r_[x[:1], xi], np.r_[dx[:1], dxi]



def loaded_contacts(result) -> list[int]:
    """Rows of the contacts that carry a force at some sample or take a positive impulse in an impact."""
    from ..contact.tally import impulse_table

    m = result.gap.shape[0]
    if m == 0:
        return []
    _, P = impulse_table(result.impacts, m, result.info.get("contact_index"))
    tang = np.linalg.norm(result.tangential_force, axis=1) if result.t.size else np.zeros((m, 0))
    loaded = (np.abs(result.normal_force).max(axis=1, initial=0.0) > 0) | (tang.max(axis=1, initial=0.0) > 0)
    return sorted(set(np.flatnonzero(loaded | (P > 0).any(axis=1)).tolist()))


def _force_series(system, rows: list[int]) -> list[tuple[str, list[int]]]:
    """(legend label, contact rows) of each part of :func:`forces_plot` with a loaded contact among ``rows``:
    one line per part (a delamination's points, a ring's facets, a crack's front ends resolved to their
    resultant, :func:`nsfem.contact.tally.resultant`), labelled with its name and position."""
    from ..contact.tally import system_parts

    xs = np.asarray(system.model_contacts.x, dtype=float)
    loaded = set(int(k) for k in rows)
    out = []
    for part in system_parts(system):
        if loaded & set(part.rows):
            px = xs[list(part.rows)]
            lo, hi = (float(np.nanmin(px)), float(np.nanmax(px))) if np.isfinite(px).any() else (np.nan, np.nan)
            where = f"x = {lo:.3g} m" if hi - lo <= 1e-12 * max(1.0, abs(hi)) else f"x = {lo:.3g} to {hi:.3g} m"
            out.append((f"{part.name} ({where})", list(part.rows)))
    return out
