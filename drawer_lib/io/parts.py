"""The parts format ``drawer.parts/1`` (docs/formats.md#parts-drawerparts1), shared by ground truth and predictions.

A revolute or prismatic part has an ``axis`` (origin, unit direction oriented so that a positive
joint value opens the part), ``limits`` (rad or m) and the closed moving ``front`` rectangle
(centre of its outer face, outward unit normal, in-plane unit ``u``, ``size`` = [extent along u,
extent along normal x u]). A rigid part has a ``center`` and axis-aligned ``bounds``.
``ignore_boxes`` (ground truth only) mark fixed fronts that look articulated (an appliance
front, a false drawer): each has an ``id``, axis-aligned ``bounds`` and, when known, the fixed
``front`` rectangle and ``instance_id``.
"""

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from drawer_lib.errors import CaptureError, InputError
from drawer_lib.geometry.joints import joint_transform
from drawer_lib.io.images import read_json, write_json

SCHEMA = "drawer.parts/1"
KINDS = ("revolute", "prismatic", "rigid")


def _vec(x, n: int, what: str) -> tuple[float, ...]:
    a = np.asarray(x, dtype=np.float64)
    if a.shape != (n,) or not np.all(np.isfinite(a)):
        raise CaptureError(f"{what}: expected {n} finite numbers, got {x!r}")
    return tuple(float(v) for v in a)


def _unit(x, what: str) -> tuple[float, float, float]:
    v = np.asarray(_vec(x, 3, what))
    n = np.linalg.norm(v)
    if abs(n - 1.0) > 1e-3:
        raise CaptureError(f"{what}: not a unit vector (|v| = {n:.4g})")
    return tuple(float(c) for c in v / n)


@dataclass(frozen=True)
class Front:
    center: tuple[float, float, float]
    normal: tuple[float, float, float]
    u: tuple[float, float, float]
    size: tuple[float, float]

    @property
    def v(self) -> np.ndarray:
        """In-plane unit vector normal x u (the direction of ``size[1]``)."""
        return np.cross(np.asarray(self.normal), np.asarray(self.u))

    def corners(self) -> np.ndarray:
        """[4, 3] corners in the order (-u,-v), (+u,-v), (+u,+v), (-u,+v)."""
        c, u, v = np.asarray(self.center), np.asarray(self.u), self.v
        hw, hh = self.size[0] / 2, self.size[1] / 2
        return np.stack([c - hw * u - hh * v, c + hw * u - hh * v, c + hw * u + hh * v, c - hw * u + hh * v])

    def to_json(self) -> dict:
        return {"center": list(self.center), "normal": list(self.normal), "u": list(self.u), "size": list(self.size)}

    @staticmethod
    def from_json(d: dict, what: str) -> "Front":
        try:
            f = Front(
                _vec(d["center"], 3, f"{what}.center"),
                _unit(d["normal"], f"{what}.normal"),
                _unit(d["u"], f"{what}.u"),
                _vec(d["size"], 2, f"{what}.size"),
            )
        except KeyError as e:
            raise CaptureError(f"{what}: missing key {e}") from e
        if abs(np.dot(f.normal, f.u)) > 1e-3:
            raise CaptureError(f"{what}: u is not perpendicular to normal")
        if min(f.size) < 0:
            raise CaptureError(f"{what}.size: negative extent {f.size}")
        return f


@dataclass(frozen=True)
class Axis:
    origin: tuple[float, float, float]
    direction: tuple[float, float, float]


@dataclass(frozen=True)
class Part:
    id: str
    kind: str  # revolute | prismatic | rigid
    axis: Axis | None = None
    limits: tuple[float, float] | None = None
    front: Front | None = None
    instance_id: int | None = None
    center: tuple[float, float, float] | None = None
    bounds: tuple[tuple[float, float, float], tuple[float, float, float]] | None = None
    extra: dict = field(default_factory=dict)  # free-form details (e.g. "family": "drawer")

    @property
    def articulated(self) -> bool:
        return self.kind in ("revolute", "prismatic")

    def to_json(self) -> dict:
        d: dict = {"id": self.id, "kind": self.kind}
        if self.articulated:
            d["axis"] = {"origin": list(self.axis.origin), "direction": list(self.axis.direction)}
            d["limits"] = list(self.limits)
            d["front"] = self.front.to_json()
        else:
            d["center"] = list(self.center)
            d["bounds"] = [list(self.bounds[0]), list(self.bounds[1])]
        if self.instance_id is not None:
            d["instance_id"] = int(self.instance_id)
        d.update(self.extra)
        return d


@dataclass(frozen=True)
class IgnoreBox:
    id: str
    bounds: tuple[tuple[float, float, float], tuple[float, float, float]]
    front: Front | None = None
    instance_id: int | None = None

    def contains(self, p) -> bool:
        p = np.asarray(p)
        return bool(np.all(p >= np.asarray(self.bounds[0])) and np.all(p <= np.asarray(self.bounds[1])))

    def to_json(self) -> dict:
        d: dict = {"id": self.id, "bounds": [list(self.bounds[0]), list(self.bounds[1])]}
        if self.front is not None:
            d["front"] = self.front.to_json()
        if self.instance_id is not None:
            d["instance_id"] = int(self.instance_id)
        return d


@dataclass(frozen=True)
class PartsFile:
    parts: tuple[Part, ...]
    ignore_boxes: tuple[IgnoreBox, ...] = ()
    units: str = "m"
    up: tuple[float, float, float] = (0.0, 0.0, 1.0)

    def by_id(self, pid: str) -> Part:
        for p in self.parts:
            if p.id == pid:
                return p
        raise KeyError(pid)

    def kinds(self) -> dict[str, int]:
        out = {k: 0 for k in KINDS}
        for p in self.parts:
            out[p.kind] += 1
        return out

    def to_json(self) -> dict:
        return {
            "schema": SCHEMA,
            "units": self.units,
            "up": list(self.up),
            "parts": [p.to_json() for p in self.parts],
            "ignore_boxes": [b.to_json() for b in self.ignore_boxes],
        }


_PART_KEYS = {"id", "kind", "axis", "limits", "front", "instance_id", "center", "bounds"}


def _bounds(b, what: str):
    try:
        lo, hi = _vec(b[0], 3, what), _vec(b[1], 3, what)
    except (TypeError, IndexError) as e:
        raise CaptureError(f"{what}: expected [[x, y, z], [x, y, z]]") from e
    if any(a > c for a, c in zip(lo, hi)):
        raise CaptureError(f"{what}: min {lo} exceeds max {hi}")
    return lo, hi


def parse_parts(d: dict, source: str = "a parts file") -> PartsFile:
    """Validate a parsed ``drawer.parts/1`` document; errors name ``source`` and the part."""
    if not isinstance(d, dict) or d.get("schema") != SCHEMA:
        raise CaptureError(f"{source}: schema is {d.get('schema') if isinstance(d, dict) else None!r}, expected {SCHEMA!r}")
    parts, seen = [], set()
    for i, p in enumerate(d.get("parts", [])):
        what = f"{source}: parts[{i}] ({p.get('id', '?')})"
        pid, kind = p.get("id"), p.get("kind")
        if not isinstance(pid, str) or not pid:
            raise CaptureError(f"{what}: missing id")
        if pid in seen:
            raise CaptureError(f"{what}: duplicate id")
        seen.add(pid)
        if kind not in KINDS:
            raise CaptureError(f"{what}: kind {kind!r} is not one of {KINDS}")
        inst = p.get("instance_id")
        extra = {k: v for k, v in p.items() if k not in _PART_KEYS}
        if kind in ("revolute", "prismatic"):
            try:
                axis = Axis(_vec(p["axis"]["origin"], 3, f"{what}.axis.origin"), _unit(p["axis"]["direction"], f"{what}.axis.direction"))
                limits = _vec(p["limits"], 2, f"{what}.limits")
                front = Front.from_json(p["front"], f"{what}.front")
            except (KeyError, TypeError) as e:
                raise CaptureError(f"{what}: missing or malformed {e}") from e
            if limits[0] >= limits[1]:
                raise CaptureError(f"{what}.limits: lower {limits[0]} must be below upper {limits[1]} (an empty "
                                   "range cannot move)")
            parts.append(Part(pid, kind, axis, limits, front, inst, extra=extra))
        else:
            try:
                center = _vec(p["center"], 3, f"{what}.center")
                bounds = _bounds(p["bounds"], f"{what}.bounds")
            except KeyError as e:
                raise CaptureError(f"{what}: missing {e}") from e
            parts.append(Part(pid, kind, center=center, bounds=bounds, instance_id=inst, extra=extra))
    boxes = []
    for i, b in enumerate(d.get("ignore_boxes", [])):
        what = f"{source}: ignore_boxes[{i}]"
        if "bounds" not in b:
            raise CaptureError(f"{what}: missing bounds")
        boxes.append(
            IgnoreBox(
                str(b.get("id", f"ignore_{i}")),
                _bounds(b["bounds"], f"{what}.bounds"),
                Front.from_json(b["front"], f"{what}.front") if "front" in b else None,
                b.get("instance_id"),
            )
        )
    return PartsFile(tuple(parts), tuple(boxes), d.get("units", "m"), tuple(d.get("up", (0, 0, 1))))


def read_parts(path: Path) -> PartsFile:
    return parse_parts(read_json(path), str(path))


def write_parts(path: Path, parts: PartsFile) -> None:
    write_json(path, parts.to_json())


def joint_motion(part: Part, q: float) -> tuple[np.ndarray, np.ndarray]:
    """(R [3, 3], t [3]) of the part's body at joint value ``q`` (rad or m)
    (:func:`drawer_lib.geometry.joints.joint_transform`; positive q opens); an
    unusable axis or q is an error naming the part."""
    if not part.articulated:
        raise InputError(f"part {part.id}: {part.kind} parts have no joint")
    a = np.asarray(part.axis.direction, np.float64)
    if not np.all(np.isfinite(a)) or np.linalg.norm(a) < 1e-9 or not np.isfinite(q):
        raise InputError(f"part {part.id}: axis direction {part.axis.direction} or q = {q} is not usable")
    T = joint_transform(part.kind, np.asarray(part.axis.origin, np.float64), a, q)
    return T[:3, :3], T[:3, 3]
