"""Low-level description of a beam stack: segments, junctions, supports, contact points.

Every scene, whatever its form, becomes a :class:`BeamStack`. It is plain data
(frozen dataclasses in SI units) and can be built directly in Python::

    >>> s = Segment("bar", 0.0, 1.0, width=0.02, height=0.01)
    >>> stack = BeamStack(segments=(s,), supports=(Support("bar", 0.0, ("U", "V", "W")),))
    >>> stack.validate() is stack
    True
    >>> round(s.I_y / s.I_z, 6)     # I_y bends W (x-z plane), I_z bends V (x-y plane)
    0.25

Conventions (design section 3): x along the shaft, z normal to delamination planes,
a segment's centroid sits at ``offset = (y_c, z_c)`` from the rotation axis.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from .errors import SceneError

FIELDS = ("U", "V", "W")
#: Names of the dofs a support can fix at a segment end (a prime is a slope).
SUPPORT_DOFS = ("U", "V", "W", "V'", "W'")
NORMALS = ("+x", "-x", "+y", "-y", "+z", "-z")
WEIGHTINGS = ("dirac", "hat")
THEORIES = ("euler-bernoulli", "rayleigh")


@dataclass(frozen=True)
class Segment:
    """An Euler-Bernoulli beam on [start, end] with a rectangular section."""

    name: str
    start: float
    end: float
    width: float = 0.02
    height: float = 0.02
    offset: tuple[float, float] = (0.0, 0.0)
    E: float = 2.1e11
    rho: float = 7500.0

    @property
    def length(self) -> float:
        return self.end - self.start

    @property
    def area(self) -> float:
        return self.width * self.height

    @property
    def I_y(self) -> float:
        """Second moment for bending in the x-z plane (field W): b h^3 / 12."""
        return self.width * self.height**3 / 12.0

    @property
    def I_z(self) -> float:
        """Second moment for bending in the x-y plane (field V): h b^3 / 12."""
        return self.height * self.width**3 / 12.0


@dataclass(frozen=True)
class Junction:
    """Rigid cross-section at ``x``: each slave's end is carried by the master (design sec. 3)."""

    x: float
    master: str
    slaves: tuple[str, ...]


@dataclass(frozen=True)
class Support:
    """Dofs fixed to zero at the end ``x`` of a segment (names from :data:`SUPPORT_DOFS`)."""

    segment: str
    x: float
    fix: tuple[str, ...]


@dataclass(frozen=True)
class Contact:
    """One unilateral contact point.

    ``kind = "interface"``: between ``segments = (upper, lower)``, gap W_upper - W_lower.
    ``kind = "obstacle"``: a rigid stop at segment ``segments[0]``, gap clearance - n.u.
    ``extent`` is the support (a, b) of the hat weight when ``weighting = "hat"`` (eq. 19).
    """

    kind: str
    x: float
    segments: tuple[str, ...]
    weighting: str = "dirac"
    extent: tuple[float, float] | None = None
    normal: str = "+z"
    clearance: float = 0.0
    friction: float = 0.0
    friction_directions: int = 4
    restitution: float = 0.0
    label: str = ""


@dataclass(frozen=True)
class BeamStack:
    """A beam stack: the geometry and contacts the finite-element model is built from."""

    segments: tuple[Segment, ...]
    junctions: tuple[Junction, ...] = ()
    supports: tuple[Support, ...] = ()
    contacts: tuple[Contact, ...] = ()
    theory: str = "euler-bernoulli"
    _index: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    def segment(self, name: str) -> Segment:
        if not self._index:
            self._index.update({s.name: s for s in self.segments})
        try:
            return self._index[name]
        except KeyError:
            raise SceneError("segment", f"no segment named {name!r}") from None

    def required_nodes(self, name: str) -> list[float]:
        """x coordinates a mesh of segment ``name`` must contain (ends, contacts, hat extents)."""
        seg = self.segment(name)
        xs = {seg.start, seg.end}
        for c in self.contacts:
            if name in c.segments:
                xs.add(c.x)
                if c.extent is not None:
                    xs.update(c.extent)
        return sorted(xs)

    def validate(self) -> "BeamStack":
        """Check consistency; raise :class:`SceneError` naming the offending item."""
        if not self.segments:
            raise SceneError("segment", "a beam stack needs at least one segment")
        if self.theory not in THEORIES:
            raise SceneError("beam.theory", f"unknown theory {self.theory!r} (use {' | '.join(THEORIES)})")
        names = [s.name for s in self.segments]
        for i, s in enumerate(self.segments):
            key = f"segment.{i}"
            if names.count(s.name) > 1:
                raise SceneError(f"{key}.name", f"duplicate segment name {s.name!r}")
            for attr in ("start", "end", "width", "height", "E", "rho", *("offset",)):
                vals = getattr(s, attr) if attr == "offset" else (getattr(s, attr),)
                if not all(isinstance(v, (int, float)) and math.isfinite(v) for v in vals):
                    raise SceneError(f"{key}.{attr}", "must be a finite number")
            for attr in ("width", "height", "E", "rho"):
                if getattr(s, attr) <= 0:
                    raise SceneError(f"{key}.{attr}", f"must be positive, got {getattr(s, attr)}")
            if not s.start < s.end:
                raise SceneError(f"{key}.end", f"must exceed start ({s.start}), got {s.end}")
        slaved: set[tuple[str, float]] = set()
        for i, j in enumerate(self.junctions):
            key = f"junction.{i}"
            self._check_end(f"{key}.master", j.master, j.x)
            if not j.slaves:
                raise SceneError(f"{key}.slaves", "a junction needs at least one slave segment")
            for s in j.slaves:
                self._check_end(f"{key}.slaves", s, j.x)
                if s == j.master or (s, j.x) in slaved:
                    raise SceneError(f"{key}.slaves", f"segment {s!r} is attached twice at x={j.x}")
                slaved.add((s, j.x))
        for i, sup in enumerate(self.supports):
            key = f"support.{i}"
            self._check_end(f"{key}.segment", sup.segment, sup.x)
            bad = [d for d in sup.fix if d not in SUPPORT_DOFS]
            if bad:
                raise SceneError(f"{key}.fix", f"unknown dof {bad[0]!r} (use {', '.join(SUPPORT_DOFS)})")
        seen = set()
        for i, c in enumerate(self.contacts):
            key = c.label or f"contact.{i}"
            self._check_contact(key, c)
            ident = (c.kind, c.segments, c.x, c.normal)
            if ident in seen:
                raise SceneError(f"{key}.x", f"duplicate contact point at x={c.x}")
            seen.add(ident)
        return self

    def _check_end(self, key: str, name: str, x: float) -> None:
        if name not in {s.name for s in self.segments}:
            raise SceneError(key, f"no segment named {name!r}")
        s = self.segment(name)
        if x not in (s.start, s.end):
            raise SceneError(key, f"x={x} is not an end of segment {name!r} [{s.start}, {s.end}]")

    def _check_contact(self, key: str, c: Contact) -> None:
        names = {s.name for s in self.segments}
        if c.kind not in ("interface", "obstacle"):
            raise SceneError(f"{key}.kind", f"unknown contact kind {c.kind!r} (use interface | obstacle)")
        want = 2 if c.kind == "interface" else 1
        if len(c.segments) != want or any(n not in names for n in c.segments):
            raise SceneError(f"{key}.segments", f"a {c.kind} contact needs {want} existing segment name(s)")
        for n in c.segments:
            s = self.segment(n)
            if not s.start <= c.x <= s.end:
                raise SceneError(f"{key}.x", f"x={c.x} lies outside segment {n!r} [{s.start}, {s.end}]")
        if c.kind == "interface":
            up, lo = (self.segment(n) for n in c.segments)
            if up.name == lo.name:
                raise SceneError(f"{key}.segments", "an interface needs two different segments")
            if (up.start, up.end) != (lo.start, lo.end):
                raise SceneError(f"{key}.segments", "interface segments must span the same x-range")
            # [upper, lower]: the gap W_upper - W_lower opens upwards only if upper lies on top
            bottom, top = up.offset[1] - up.height / 2, lo.offset[1] + lo.height / 2
            if up.offset[0] != lo.offset[0] or abs(bottom - top) > 1e-9 * max(up.height, lo.height):
                raise SceneError(f"{key}.segments", f"{up.name!r} must sit on {lo.name!r}: its bottom face "
                                 f"(z = {bottom:.6g}) must meet the other's top face (z = {top:.6g}) at the same y")
            if not up.start < c.x < up.end:
                raise SceneError(f"{key}.x", f"x={c.x} must lie strictly inside the interface ({up.start}, {up.end})")
        if c.weighting not in WEIGHTINGS:
            raise SceneError(f"{key}.weighting", f"unknown weighting {c.weighting!r} (use dirac | hat)")
        if c.weighting == "hat":
            if c.extent is None or not c.extent[0] < c.x < c.extent[1]:
                raise SceneError(f"{key}.extent", "a hat weight needs an extent (a, b) with a < x < b")
            for n in c.segments:
                s = self.segment(n)
                if not (s.start <= c.extent[0] and c.extent[1] <= s.end):
                    raise SceneError(f"{key}.extent", f"hat extent leaves segment {n!r}")
        if c.normal not in NORMALS:
            raise SceneError(f"{key}.normal", f"unknown normal {c.normal!r} (use {' | '.join(NORMALS)})")
        if not (math.isfinite(c.clearance) and c.clearance >= 0):
            raise SceneError(f"{key}.clearance", f"must be finite and >= 0, got {c.clearance}")
        if not (math.isfinite(c.friction) and c.friction >= 0):
            raise SceneError(f"{key}.friction", f"must be finite and >= 0, got {c.friction}")
        if not (0.0 <= c.restitution <= 1.0):
            raise SceneError(f"{key}.restitution", f"must lie in [0, 1], got {c.restitution}")
        r = c.friction_directions
        if isinstance(r, bool) or not isinstance(r, int) or r < 2 or r % 2:
            raise SceneError(f"{key}.friction_directions", f"must be an even integer >= 2, got {r}")
