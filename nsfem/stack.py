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
from dataclasses import dataclass, field, replace

import numpy as np

from .errors import SceneError

FIELDS = ("U", "V", "W")
#: Names of the dofs a support can fix at a segment end (a prime is a slope).
SUPPORT_DOFS = ("U", "V", "W", "V'", "W'")
NORMALS = ("+x", "-x", "+y", "-y", "+z", "-z")
WEIGHTINGS = ("dirac", "hat")
THEORIES = ("euler-bernoulli", "rayleigh", "timoshenko")
#: Shear coefficients of a circle (Timoshenko theory): Cowper's (ROSS's default) or Hutchinson's
SHEAR_COEFFICIENTS = ("cowper", "hutchinson")
#: Poisson's ratio of the default shear modulus G = E / (2 (1 + nu))
DEFAULT_POISSON = 0.3


SECTIONS = ("rectangle", "circle")


@dataclass(frozen=True)
class Segment:
    """A beam on [start, end]: a rectangular section (``width`` b along y, ``height`` h along z) or a
    circular one (``section = "circle"``: outer diameter ``width`` = ``height``, bore ``inner``).

    >>> s = Segment("tube", 0.0, 1.0, 0.05, 0.05, section="circle", inner=0.03)
    >>> round(s.area / (3.141592653589793 / 4 * (0.05**2 - 0.03**2)), 12), s.I_y == s.I_z
    (1.0, True)
    """

    name: str
    start: float
    end: float
    width: float = 0.02
    height: float = 0.02
    offset: tuple[float, float] = (0.0, 0.0)
    E: float = 2.1e11
    rho: float = 7500.0
    section: str = "rectangle"
    inner: float = 0.0
    #: shear modulus [Pa] (None: E / (2 (1 + 0.3))); only the Timoshenko theory uses it
    G: float | None = None

    @property
    def shear_modulus(self) -> float:
        """G, or E / (2 (1 + :data:`DEFAULT_POISSON`)) when the segment gives none."""
        return self.E / (2.0 * (1.0 + DEFAULT_POISSON)) if self.G is None else self.G

    @property
    def length(self) -> float:
        return self.end - self.start

    @property
    def area(self) -> float:
        if self.section == "circle":
            return math.pi / 4.0 * (self.width**2 - self.inner**2)
        return self.width * self.height

    @property
    def I_y(self) -> float:
        """Second moment for bending in the x-z plane (field W): b h^3 / 12 (circle: pi (D^4 - d^4) / 64)."""
        if self.section == "circle":
            return math.pi / 64.0 * (self.width**4 - self.inner**4)
        return self.width * self.height**3 / 12.0

    @property
    def I_z(self) -> float:
        """Second moment for bending in the x-y plane (field V): h b^3 / 12 (circle: pi (D^4 - d^4) / 64)."""
        if self.section == "circle":
            return self.I_y
        return self.height * self.width**3 / 12.0

    @property
    def axisymmetric(self) -> bool:
        """Equal bending stiffness and inertia in y and z, centroid on the axis: the section looks the
        same in every direction of the y-z plane (what the inertial frame needs)."""
        return (self.section == "circle" or self.width == self.height) and self.offset == (0.0, 0.0)


@dataclass(frozen=True)
class Disk:
    """A rigid disk at ``x`` on the rotor axis: ``mass`` on V and W, ``diametral`` inertia on the slopes
    V' and W', ``polar`` inertia about x (gyroscopic in the inertial frame, eq. in docs/theory.md).

    ``outer_diameter``, ``inner_diameter`` and ``width`` [m] are the geometry a disk was given by (0: given
    by its mass and inertias); the model uses only the mass and inertias, the VTU export draws the geometry
    (:func:`nsfem.export.vtu.disk_size`)."""

    x: float
    mass: float
    polar: float = 0.0
    diametral: float = 0.0
    label: str = ""
    outer_diameter: float = 0.0
    inner_diameter: float = 0.0
    width: float = 0.0


@dataclass(frozen=True)
class Bearing:
    """A linear spring-damper from the rotor at ``x`` to ground, lateral: force = -K (v, w) - C (v', w')
    with K = [[kyy, kyz], [kzy, kzz]], C likewise (in the frame the bearing is fixed in), and an axial
    spring ``kxx`` on U (a thrust bearing)."""

    x: float
    K: tuple[tuple[float, float], tuple[float, float]] = ((0.0, 0.0), (0.0, 0.0))
    C: tuple[tuple[float, float], tuple[float, float]] = ((0.0, 0.0), (0.0, 0.0))
    kxx: float = 0.0
    label: str = ""
    #: speed-dependent coefficients: (speeds_hz, ((name, values), ...)) with names kyy ... czz, kxx and one
    #: value per speed, interpolated linearly in speed by :meth:`at_speed` (empty: constant K, C, kxx)
    table: tuple = ()

    def at_speed(self, speed_hz: float) -> "Bearing":
        """This bearing with its table's coefficients at ``speed_hz`` (linear interpolation; a speed outside the
        table is a :class:`SceneError` naming the bearing and the range). Without a table, itself."""
        if not self.table:
            return self
        speeds, columns = self.table
        lo, hi = speeds[0], speeds[-1]
        if not lo <= speed_hz <= hi:
            raise SceneError(f"{self.label or 'bearing'}.speeds_hz", f"{speed_hz:g} Hz lies outside the bearing's "
                             f"table [{lo:g}, {hi:g}] Hz (coefficients are not extrapolated); extend the table")
        v = {name: float(np.interp(speed_hz, speeds, values)) for name, values in columns}
        K = tuple(tuple(v.get(f"k{a}{b}", self.K[i][j]) for j, b in enumerate("yz")) for i, a in enumerate("yz"))
        C = tuple(tuple(v.get(f"c{a}{b}", self.C[i][j]) for j, b in enumerate("yz")) for i, a in enumerate("yz"))
        return replace(self, K=K, C=C, kxx=v.get("kxx", self.kxx))

    @property
    def isotropic(self) -> bool:
        """K and C commute with a rotation about x (form [[a, b], [-b, a]]): the bearing looks the same
        from a frame spinning with the shaft, so the rotating frame can carry it."""
        rows = [self.at_speed(s) for s in self.table[0]] if self.table else [self]
        return all(A[0][0] == A[1][1] and A[0][1] == -A[1][0] for b in rows for A in (b.K, b.C))


@dataclass(frozen=True)
class Unbalance:
    """A mass eccentricity ``magnitude`` (kg m) at ``x``, at angle ``phase`` (rad) in the rotating frame
    from +y towards +z: a centrifugal force magnitude Omega^2 along that direction."""

    x: float
    magnitude: float
    phase: float = 0.0
    label: str = ""


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


CRACK_SIDES = ("+y", "-y", "+z", "-z")


@dataclass(frozen=True)
class Crack:
    """A transverse crack at ``x`` between the abutting ends of ``segments = (left, right)`` (design section 8).

    The two ends share U, V and W (a hinge) and differ in slope; the open crack is a rotational spring
    of ``compliance = (c_V', c_W')`` [rad / (N m)]: the relative slopes (V'_right - V'_left,
    W'_right - W'_left) = c M for a bending moment M (:mod:`nsfem.fem.crack`). The crack faces are
    contacts of kind ``"crack"`` (their gaps hold the hinge shut where the faces touch), so a closed
    crack is the intact shaft. ``depth`` is a / h (rectangle) or a / D (circle) from the face ``side``.
    """

    x: float
    segments: tuple[str, str]
    depth: float
    side: str
    compliance: tuple[float, float]
    label: str = ""


@dataclass(frozen=True)
class Contact:
    """One unilateral contact point.

    ``kind = "interface"``: between ``segments = (upper, lower)``, gap W_upper - W_lower.
    ``kind = "obstacle"``: a rigid stop at segment ``segments[0]``, gap clearance - n.u.
    ``kind = "crack"``: a point of a crack face between ``segments = (left, right)`` at ``arm = (y, z)`` from
    the rotation centre of the hinge (the ligament's centroid), gap -(y dV' + z dW') with d the right
    slope minus the left: the axial opening of the faces at that point.
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
    #: obstacle only: the normal's angle in the y-z plane from +y towards +z [rad], n = (0, cos, sin), in place of
    #: an axis (a stator's facet; ``normal`` then names the nearest axis, for display)
    angle: float | None = None
    #: a stator's facet: the radius [m] of the shaft surface it touches, which slides past it at Omega times
    #: this radius (the constant part of the slip velocity, paper eq. 27)
    radius: float = 0.0
    #: a stator's facet on an elastic ring: the ring's radial stiffness [N/m] and damping [N s/m] (0: rigid,
    #: Signorini); the facets of one ring share them (:mod:`nsfem.contact.ring`)
    stiffness: float = 0.0
    damping: float = 0.0
    #: a crack face's point: (y, z) from the hinge's rotation centre [m]
    arm: tuple[float, float] | None = None
    #: a rigid stator's facet: its ring is round in the exact method (``[[stator]] shape``,
    #: :mod:`nsfem.integrate.round`), else a polygon fixed in space
    round: bool = False

    @property
    def table_key(self) -> str:
        """The scene key of the table entry this contact came from (``stator.1`` for ``stator.1.7``, a facet of
        it; ``delamination.0`` for one of its contact points; else the label itself)."""
        head, _, tail = self.label.rpartition(".")
        return head if head.startswith(("stator.", "delamination.", "crack.")) and tail.isdigit() else self.label


@dataclass(frozen=True)
class BeamStack:
    """A beam stack: the geometry and contacts the finite-element model is built from."""

    segments: tuple[Segment, ...]
    junctions: tuple[Junction, ...] = ()
    supports: tuple[Support, ...] = ()
    contacts: tuple[Contact, ...] = ()
    theory: str = "euler-bernoulli"
    #: a circle's shear coefficient with theory = "timoshenko" (:data:`SHEAR_COEFFICIENTS`)
    shear_coefficient: str = "cowper"
    disks: tuple[Disk, ...] = ()
    bearings: tuple[Bearing, ...] = ()
    unbalances: tuple[Unbalance, ...] = ()
    cracks: tuple[Crack, ...] = ()
    _index: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    @property
    def speed_dependent(self) -> bool:
        """Some bearing has coefficients tabulated against speed."""
        return any(b.table for b in self.bearings)

    def at_speed(self, speed_hz: float) -> "BeamStack":
        """The stack with every bearing's coefficients at ``speed_hz`` (:meth:`Bearing.at_speed`)."""
        if not self.speed_dependent:
            return self
        return replace(self, bearings=tuple(b.at_speed(speed_hz) for b in self.bearings))

    def check_speeds(self, speeds_hz) -> None:
        """Refuse speeds outside any bearing's table (before a computation over them)."""
        for b in self.bearings:
            if b.table and len(speeds_hz):
                try:
                    b.at_speed(float(min(speeds_hz)))
                    b.at_speed(float(max(speeds_hz)))
                except SceneError as exc:
                    raise SceneError(exc.key, f"{exc.reason}, or choose speeds within it") from None

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
        xs.update(p.x for p in self.points() if self.carrier(p.x) == name)
        return sorted(xs)

    def points(self) -> tuple:
        """The point components on the rotor axis: disks, bearings, unbalances."""
        return self.disks + self.bearings + self.unbalances

    def carrier(self, x: float) -> str | None:
        """The segment that carries a point component at ``x``: the one segment whose span holds x (at a
        junction or a shared end, the first of them; a junction ties their V, W and slopes, a crack only
        V and W: there it is the crack's left side), None
        where two layers of a delamination both span x."""
        at = [s for s in self.segments if s.start <= x <= s.end]
        inside = [s for s in at if s.start < x < s.end]
        if len(inside) > 1:
            return None
        return (inside or at)[0].name if at else None

    def validate(self) -> "BeamStack":
        """Check consistency; raise :class:`SceneError` naming the offending item."""
        if not self.segments:
            raise SceneError("segment", "a beam stack needs at least one segment")
        if self.theory not in THEORIES:
            raise SceneError("beam.theory", f"unknown theory {self.theory!r} (use {' | '.join(THEORIES)})")
        if self.shear_coefficient not in SHEAR_COEFFICIENTS:
            raise SceneError("beam.shear_coefficient", f"unknown shear coefficient {self.shear_coefficient!r} "
                             f"(use {' | '.join(SHEAR_COEFFICIENTS)})")
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
            if s.G is not None:
                self._check_shear_modulus(f"{key}.G", s)
            if not s.start < s.end:
                raise SceneError(f"{key}.end", f"must exceed start ({s.start}), got {s.end}")
            if s.section not in SECTIONS:
                raise SceneError(f"{key}.section", f"unknown section {s.section!r} (use {' | '.join(SECTIONS)})")
            if s.section == "circle":
                if s.width != s.height:
                    raise SceneError(f"{key}.diameter", "a circular section has one diameter (width = height)")
                if not (math.isfinite(s.inner) and 0.0 <= s.inner < s.width):
                    raise SceneError(f"{key}.inner_diameter", f"must lie in [0, diameter = {s.width}), got {s.inner}")
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
            ident = (c.kind, c.segments, c.x, c.normal, c.angle, c.arm)
            if ident in seen:
                raise SceneError(f"{c.table_key or key}.x", f"duplicate contact point at x={c.x}")
            seen.add(ident)
        for p in self.points():
            self._check_point(p)
        for i, k in enumerate(self.cracks):
            self._check_crack(k.label or f"crack.{i}", k)
        return self

    @staticmethod
    def _check_shear_modulus(key: str, s: Segment) -> None:
        G = s.G
        if not (isinstance(G, (int, float)) and math.isfinite(G)) or G <= 0:
            raise SceneError(key, f"must be a positive finite number [Pa], got {G}")
        nu = s.E / (2.0 * G) - 1.0
        if not 0.0 <= nu <= 0.5:
            raise SceneError(key, f"G = {G:g} Pa with E = {s.E:g} Pa gives Poisson's ratio E / (2 G) - 1 = {nu:.4g}, "
                             "outside [0, 0.5] where the shear coefficients hold (G from E / 3 to E / 2)")

    def _check_crack(self, key: str, k: Crack) -> None:
        if len(k.segments) != 2:
            raise SceneError(f"{key}.segments", "a crack joins two segments (left, right)")
        left, right = (self.segment(n) for n in k.segments)
        if not (left.end == k.x == right.start):
            raise SceneError(f"{key}.x", f"x={k.x} must be the left segment's end and the right one's start")
        if (left.width, left.height, left.section, left.inner, left.offset) != \
                (right.width, right.height, right.section, right.inner, right.offset):
            raise SceneError(f"{key}.x", "the two sides of a crack must have the same section")
        if k.side not in CRACK_SIDES:
            raise SceneError(f"{key}.side", f"unknown side {k.side!r} (use {' | '.join(CRACK_SIDES)})")
        if not (0.0 < k.depth < 1.0):
            raise SceneError(f"{key}.depth", f"must lie in (0, 1), got {k.depth}")
        if not all(math.isfinite(c) and c > 0.0 for c in k.compliance):
            raise SceneError(f"{key}.depth", f"compliance must be positive and finite, got {k.compliance}")

    def _check_point(self, p) -> None:
        kind = type(p).__name__.lower()
        key = p.label or kind
        if not math.isfinite(p.x) or self.carrier(p.x) is None:
            lo, hi = min(s.start for s in self.segments), max(s.end for s in self.segments)
            if math.isfinite(p.x) and lo <= p.x <= hi:
                raise SceneError(f"{key}.x", f"x={p.x} lies where two layers of a delamination run side by side; "
                                 f"a {kind} sits on the intact shaft")
            raise SceneError(f"{key}.x", f"x={p.x} lies outside the rotor [{lo}, {hi}]")
        values = {"Disk": ("mass", "polar", "diametral"), "Unbalance": ("magnitude",),
                  "Bearing": ("kxx",)}[type(p).__name__]
        scene_names = {"polar": "polar_inertia", "diametral": "diametral_inertia"}
        for name in values:
            v = getattr(p, name)
            if not (math.isfinite(v) and v >= 0.0):
                raise SceneError(f"{key}.{scene_names.get(name, name)}", f"must be finite and >= 0, got {v}")
        if isinstance(p, Disk) and p.mass <= 0.0:
            raise SceneError(f"{key}.mass", f"must be positive, got {p.mass}")
        if isinstance(p, Bearing) and p.table:   # every row of its table is a bearing of its own
            for s in p.table[0]:
                self._check_point(replace(p.at_speed(s), table=()))
        if isinstance(p, Bearing):
            for sym, A in (("k", p.K), ("c", p.C)):
                for i, a in enumerate("yz"):
                    for j, b in enumerate("yz"):
                        if not math.isfinite(A[i][j]):
                            raise SceneError(f"{key}.{sym}{a}{b}", f"must be finite, got {A[i][j]}")
                # a bearing may not feed energy in when the shaft stands still: the symmetric part of
                # K and of C must be positive semidefinite (cross terms beyond that are circulatory)
                # halves before the sum and products, not powers: 1e300 entries give inf, never OverflowError
                sym_part = [[A[i][j] / 2 + A[j][i] / 2 for j in range(2)] for i in range(2)]
                det = sym_part[0][0] * sym_part[1][1] - sym_part[0][1] * sym_part[0][1]
                if sym_part[0][0] < 0 or sym_part[1][1] < 0 or det < -1e-12 * (sym_part[0][0] * sym_part[1][1]):
                    # the entry at fault: a negative diagonal one, else the larger cross term
                    at = ("yy" if sym_part[0][0] < 0 else "zz" if sym_part[1][1] < 0 else
                          "yz" if abs(A[0][1]) >= abs(A[1][0]) else "zy")
                    raise SceneError(f"{key}.{sym}{at}", f"the symmetric part of [[{sym}yy, {sym}yz], [{sym}zy, "
                                     f"{sym}zz]] = {[list(r) for r in A]} must be positive semidefinite "
                                     "(else the bearing feeds energy in at rest)")

    def _check_end(self, key: str, name: str, x: float) -> None:
        if name not in {s.name for s in self.segments}:
            raise SceneError(key, f"no segment named {name!r}")
        s = self.segment(name)
        if x not in (s.start, s.end):
            raise SceneError(key, f"x={x} is not an end of segment {name!r} [{s.start}, {s.end}]")

    def _check_contact(self, key: str, c: Contact) -> None:
        names = {s.name for s in self.segments}
        if c.kind not in ("interface", "obstacle", "crack"):
            raise SceneError(f"{key}.kind", f"unknown contact kind {c.kind!r} (use interface | obstacle | crack)")
        if c.kind == "crack":
            if c.arm is None or not any(k.segments == c.segments and k.x == c.x for k in self.cracks):
                raise SceneError(f"{key}.segments", "a crack face's point needs its crack (and an arm)")
            if c.friction > 0.0:
                raise SceneError(f"{key}.friction", "the crack's hinge shares the faces' displacements, so they "
                                 "cannot slide: face friction has no effect in this model")
            return
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
        if c.angle is not None and (c.kind != "obstacle" or not math.isfinite(c.angle)):
            raise SceneError(f"{key}.angle", "an angled normal needs an obstacle and a finite angle")
        if not (math.isfinite(c.clearance) and c.clearance >= 0):
            raise SceneError(f"{key}.clearance", f"must be finite and >= 0, got {c.clearance}")
        if not (math.isfinite(c.friction) and c.friction >= 0):
            raise SceneError(f"{key}.friction", f"must be finite and >= 0, got {c.friction}")
        if not (0.0 <= c.restitution <= 1.0):
            raise SceneError(f"{key}.restitution", f"must lie in [0, 1], got {c.restitution}")
        r = c.friction_directions
        if isinstance(r, bool) or not isinstance(r, int) or r < 2 or r % 2:
            raise SceneError(f"{key}.friction_directions", f"must be an even integer >= 2, got {r}")
