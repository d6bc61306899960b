"""The rigid-body motions a model leaves free, named: what no support or bearing restrains.

The stiffness of a beam stack (no torsion field) is singular on the rigid motions its supports admit
and its bearings do not resist (:func:`nsfem.fem.rigid.rigid_modes`): axial travel (U), and in each
lateral plane a translation and a tilt. They are found once from the model, in the rigid-motion
coordinates (u0, v0, tv, w0, tw) of each connected part, and said in a rotor engineer's words with the
scene key that restrains them. A free axial motion is harmless for the lateral dynamics (it is a 0 Hz
mode of its own), but a stationary state needs an invertible stiffness.

>>> from nsfem import build_model, load_scene
>>> free_motions(build_model(load_scene("ross_example", ["bearing.2.kxx=0", "mesh.elements=6"])))
['axial rigid motion (U)']
"""

from __future__ import annotations

import numpy as np

def _plane(coef: np.ndarray, plane: str) -> list[str]:
    """The free motions in one lateral plane from the coefficient rows (translation, tilt) of a basis whose
    coefficients over all rigid motions are at most 1."""
    t, r = coef
    rank = np.linalg.matrix_rank(np.vstack([t, r]), tol=1e-9)   # coef normalized to a largest entry 1
    if rank == 0:
        return []
    axis = "x-y" if plane == "y" else "x-z"
    if rank == 2:
        return [f"rigid lateral translation and tilt in the {axis} plane"]
    k = int(np.argmax(np.hypot(t, r)))
    if abs(r[k]) <= 1e-9 * abs(t[k]):
        return [f"rigid lateral translation along {plane}"]
    x0 = -t[k] / r[k]
    return [f"rigid tilt in the {axis} plane about x = {0.0 if abs(x0) < 1e-9 else x0:.4g} m"]


def free_motions(model, Q_full=None) -> list[str]:
    """Names of the rigid motions of ``model`` that neither its supports nor its bearings restrain; with
    ``Q_full`` (a stiffness in full coordinates, e.g. at speed) only those on which it is singular too
    (|Q B c| at round-off of |Q| |B c|: centrifugal softening makes a free lateral motion of a spinning
    rotor a negative stiffness, not a singular one)."""
    from ..fem.rigid import components, rigid_fields, rigid_modes

    A = rigid_modes(model, model.T)
    if A.shape[1] == 0:
        return []
    B = np.asarray(model.T @ A)
    if Q_full is not None:
        B = B / np.linalg.norm(B, axis=0)
        w, V = np.linalg.eigh(B.T @ B)
        B = B @ V / np.sqrt(w)                        # orthonormal columns
        s, Vt = np.linalg.svd(np.asarray(Q_full @ B), full_matrices=False)[1:]
        B = B @ Vt[s <= 1e-12 * float(abs(Q_full).max()) * np.sqrt(B.shape[0])].T
        if B.shape[1] == 0:
            return []
    R = rigid_fields(model)
    C = np.linalg.lstsq(R, B, rcond=None)[0]      # (5 parts) x k: u0, v0, tv, w0, tw per part
    C = C / np.abs(C).max()
    out: list[str] = []
    parts = components(model.stack)
    for p in range(len(parts)):
        u0, v0, tv, w0, tw = C[5 * p:5 * p + 5]
        where = f" of {', '.join(parts[p])}" if len(parts) > 1 else ""
        names = (["axial rigid motion (U)"] if np.abs(u0).max() > 1e-9 else []) + _plane(np.vstack([v0, tv]), "y") \
            + _plane(np.vstack([w0, tw]), "z")
        out += [n + where for n in names]
    return out


def restraints(names: list[str]) -> str:
    """The scene keys that restrain the named motions (:func:`free_motions`).

    >>> restraints(["axial rigid motion (U)", "lateral rigid translation along z"])
    "a bearing's kxx (axial thrust stiffness: x is the shaft axis), bearings' kzz, or shaft.supports"
    """
    axial = any(n.startswith("axial") for n in names)
    lateral = [p for p, tags in (("kyy", ("along y", "x-y")), ("kzz", ("along z", "x-z")))
               if any(t in n for n in names for t in tags)]
    keys = (["a bearing's kxx (axial thrust stiffness: x is the shaft axis)"] if axial else []) \
        + ([f"bearings' {' and '.join(lateral)}"] if lateral else [])
    return ", ".join(keys) + ", or shaft.supports" if len(keys) > 1 else f"{keys[0]} or shaft.supports"


def caught_by_contacts(model) -> bool:
    """Whether rigid stops (stator rings, obstacles) are there to catch lateral rigid motions: a rotor that
    drops into its retainer bearings is held by its contacts, not left free."""
    return any(c.kind == "obstacle" for c in model.stack.contacts)


def rigid_warning(model, caught: bool = False, names: list[str] | None = None) -> str | None:
    """The one-line warning of ``run`` and ``modes`` when the model has free rigid motions, else None;
    ``caught``: lateral motions are held by contacts (a stator, a stop: a rotor dropping into its retainer
    bearings), so only a free axial motion is said; ``names``: :func:`free_motions` of the model when known."""
    names = free_motions(model) if names is None else names
    if caught:
        names = [n for n in names if n.startswith("axial")]
    if not names:
        return None
    many = len(names) > 1
    return (f"the model has free rigid motion: {', '.join(names)}; {'they are 0 Hz modes' if many else 'it is a 0 Hz mode'} "
            f"(restrain {'them' if many else 'it'} with {restraints(names)})")


def rigid_error(model, Q_full) -> str | None:
    """The message of ``stationary`` refusing a model whose free rigid motions leave ``Q_full`` singular, else
    None."""
    names = free_motions(model, Q_full)
    if not names:
        return None
    text = (f"no stationary state: {', '.join(names)} {'are' if len(names) > 1 else 'is'} unrestrained, so the "
            f"stiffness Q is singular; restrain {'them' if len(names) > 1 else 'it'} with {restraints(names)}")
    if caught_by_contacts(model) and any(not n.startswith("axial") for n in names):
        text += (" (the stators or stops that catch the lateral motion act only through the contact problem, which "
                 "needs Q invertible; `nsfem run` computes the rotor falling onto them)")
    return text


__all__ = ["caught_by_contacts", "free_motions", "restraints", "rigid_error", "rigid_warning"]
