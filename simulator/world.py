"""Worlds: static walls, named start poses, an optional border and named markers, in metres.

The border is a closed polygon inside the world that means nothing to the physics: it is there
for whoever needs an outline of the world (an application's boundary to follow or to protect,
the snapshot's dashed line); without one, the walls serve (`World.border_segments`).

Two file formats load into the same `World`:

* **YAML** (ours, documented in docs/worlds.md)::

      name: arena
      walls:
        - segment: [x1, y1, x2, y2]          # metres
        - polygon: [[x, y], [x, y], ...]     # closed outline
        - polyline: [[x, y], [x, y], ...]    # open chain
      robots:                                 # named start poses: x, y, theta in degrees
        robot1: [-10.0, 0.0, 0]
      border: [[x, y], ...]                   # optional closed polygon inside the world
      markers:                                # optional named points the snapshot marks
        t1: [x, y]

* **MobileSim `.map`** (the original's maps): the `LINES` section (x1 y1 x2 y2 in millimetres) and
  `Cairn: RobotHome x y theta` start poses (named home0, home1, … in file order). Other sections
  (points, goals, forbidden areas, `DATA`) are skipped and listed in `World.notes`.

A malformed file raises ConfigError naming file and line — a user's first map is usually hand
written, and "line 14" is the whole diagnosis. Coordinates must lie within
mrta_zenoh.limits.COORDINATE (10 km of the origin): a finite wall at 1e308 m overflows the ray
caster and the physics, and no robot drives that far.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mrta_zenoh.errors import ConfigError
from mrta_zenoh.limits import COORDINATE
from mrta_zenoh.yamlfile import YamlDoc, did_you_mean, load_yaml, read_bounded


@dataclass(frozen=True)
class Pose:
    x: float
    y: float
    theta: float  # radians

    @classmethod
    def from_degrees(cls, x: float, y: float, theta_deg: float) -> "Pose":
        return cls(float(x), float(y), math.radians(theta_deg))


@dataclass
class World:
    name: str
    walls: np.ndarray  # (W, 4): x1, y1, x2, y2 in metres
    starts: dict[str, Pose] = field(default_factory=dict)
    border: np.ndarray | None = None  # (B, 2) closed polygon, or None
    # named points the snapshot marks (an application's places: delivery's tasks); like the
    # border they mean nothing to the physics, and the simulator knows no application by them
    markers: dict[str, tuple[float, float]] = field(default_factory=dict)
    source: str = ""
    notes: list[str] = field(default_factory=list)

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """(xmin, ymin, xmax, ymax) of walls, starts and border; a 10 m square if empty."""
        xs = list(self.walls[:, 0]) + list(self.walls[:, 2])
        ys = list(self.walls[:, 1]) + list(self.walls[:, 3])
        xs += [p.x for p in self.starts.values()]
        ys += [p.y for p in self.starts.values()]
        if self.border is not None:
            xs += list(self.border[:, 0])
            ys += list(self.border[:, 1])
        if not xs:
            return (-5.0, -5.0, 5.0, 5.0)
        return (min(xs), min(ys), max(xs), max(ys))

    def border_segments(self) -> np.ndarray:
        """The border as (B, 4) segments; the world's walls when no border was given."""
        if self.border is None:
            return self.walls
        b = self.border
        return np.hstack([b, np.roll(b, -1, axis=0)])


def load_world(path: Path | str) -> World:
    path = Path(path)
    if path.suffix.lower() == ".map":
        return load_mobilesim_map(path)
    if path.suffix.lower() in (".yaml", ".yml"):
        return load_yaml_world(path)
    raise ConfigError("unknown world format: expected a .yaml/.yml world or a MobileSim .map",
                      file=str(path))


# ------------------------------------------------------------------------ MobileSim .map

def load_mobilesim_map(path: Path) -> World:
    text = read_bounded(path, "a MobileSim map").decode("latin-1")
    lines = text.splitlines()
    if not lines or not lines[0].strip().startswith("2D-Map"):
        raise ConfigError("not a MobileSim map: the first line must be '2D-Map'", file=str(path),
                          line=1)
    walls: list[tuple[float, float, float, float]] = []
    starts: dict[str, Pose] = {}
    notes: list[str] = []
    section = "header"
    declared_lines: tuple[int, int] | None = None
    for n, raw in enumerate(lines[1:], start=2):
        line = raw.strip()
        if not line:
            continue
        if line.isupper() and ":" not in line and " " not in line:  # LINES, DATA, POINTS…
            section = line
            if line != "LINES":
                notes.append(f"section {line} (line {n}) skipped")
            continue
        if section == "LINES":
            parts = line.split()
            if len(parts) != 4:
                raise ConfigError(f"a LINES entry needs 4 numbers (x1 y1 x2 y2 in mm), got "
                                  f"{len(parts)}: {line!r}", file=str(path), line=n)
            try:
                x1, y1, x2, y2 = (_finite(p) / 1000.0 for p in parts)
            except ValueError:
                raise ConfigError(f"a LINES entry must be finite numbers, got {line!r}",
                                  file=str(path), line=n) from None
            _in_world((x1, y1, x2, y2), path, n, "a LINES entry (mm / 1000)")
            walls.append((x1, y1, x2, y2))
            continue
        if section != "header":
            continue  # DATA points and unknown sections: skipped, noted once above
        keyword, _, rest = line.partition(":")
        keyword = keyword.strip()
        if keyword == "Cairn":
            fields = rest.split()
            if fields and fields[0] == "RobotHome":
                try:
                    x, y, th = (_finite(v) for v in fields[1:4])
                except ValueError:
                    raise ConfigError(f"Cairn RobotHome needs x y theta numbers: {line!r}",
                                      file=str(path), line=n) from None
                _in_world((x / 1000.0, y / 1000.0), path, n, "Cairn RobotHome (mm / 1000)")
                starts[f"home{len(starts)}"] = Pose.from_degrees(x / 1000.0, y / 1000.0, th)
            else:
                notes.append(f"Cairn {fields[0] if fields else '?'} (line {n}) skipped")
        elif keyword == "NumLines":
            declared_lines = (int(_number(rest, path, n)), n)
        elif keyword in ("LineMinPos", "LineMaxPos", "LinesAreSorted", "MinPos", "MaxPos",
                         "NumPoints", "PointsAreSorted", "Resolution"):
            pass
        else:
            notes.append(f"header {keyword!r} (line {n}) skipped")
    if declared_lines is not None and declared_lines[0] != len(walls):
        raise ConfigError(f"NumLines says {declared_lines[0]} but LINES has {len(walls)} entries",
                          file=str(path), line=declared_lines[1])
    return World(name=path.stem, walls=_walls_array(walls), starts=starts, source=str(path),
                 notes=notes)


def _finite(text: str) -> float:
    x = float(text)
    if not math.isfinite(x):
        raise ValueError(f"{text!r} is not finite")
    return x


def _in_world(coords, path: Path, line: int, what: str) -> None:
    """Coordinates (metres) inside COORDINATE, or a ConfigError naming file, line and range."""
    for c in coords:
        problem = COORDINATE.problem(c)
        if problem:
            raise ConfigError(f"{what}: a coordinate {problem}", file=str(path), line=line)


def _number(text: str, path: Path, line: int) -> float:
    try:
        return _finite(text.split()[0])
    except (ValueError, IndexError):
        raise ConfigError(f"expected a number, got {text.strip()!r}", file=str(path),
                          line=line) from None


# ------------------------------------------------------------------------------- YAML

_TOP_KEYS = ("name", "walls", "robots", "border", "markers")
_WALL_KINDS = ("segment", "polygon", "polyline")


def load_yaml_world(path: Path) -> World:
    doc = load_yaml(path)
    if not isinstance(doc.data, dict):
        raise doc.error((), "a world file is a mapping with 'walls' (and optionally 'name', "
                            "'robots', 'border')")
    for key in doc.data:
        if key not in _TOP_KEYS:
            raise doc.error((key,), f"unexpected key {key!r}" + did_you_mean(key, _TOP_KEYS))
    raw_walls = doc.data.get("walls")
    if not isinstance(raw_walls, list):
        raise doc.error(("walls",), "'walls' must be a list of segment/polygon/polyline entries")
    walls: list[tuple[float, float, float, float]] = []
    for i, entry in enumerate(raw_walls):
        where = ("walls", i)
        if not isinstance(entry, dict) or len(entry) != 1:
            raise doc.error(where, "each wall is one of {segment: [x1,y1,x2,y2]}, "
                                   "{polygon: [[x,y],…]}, {polyline: [[x,y],…]}")
        (kind, value), = entry.items()
        if kind not in _WALL_KINDS:
            raise doc.error(where + (kind,), f"unknown wall kind {kind!r}"
                            + did_you_mean(kind, _WALL_KINDS))
        if kind == "segment":
            x1, y1, x2, y2 = _numbers(doc, where + (kind,), value, 4)
            walls.append((x1, y1, x2, y2))
        else:
            pts = _points(doc, where + (kind,), value, 3 if kind == "polygon" else 2)
            chain = pts + [pts[0]] if kind == "polygon" else pts
            walls.extend((a[0], a[1], b[0], b[1]) for a, b in zip(chain, chain[1:]))
    starts: dict[str, Pose] = {}
    robots = doc.data.get("robots") or {}
    if not isinstance(robots, dict):
        raise doc.error(("robots",), "'robots' maps a name to [x, y, theta_degrees]")
    for name, value in robots.items():
        x, y, th = _numbers(doc, ("robots", name), value, 3, coordinates=2)
        starts[str(name)] = Pose.from_degrees(x, y, th)
    border = None
    if doc.data.get("border") is not None:
        border = np.array(_points(doc, ("border",), doc.data["border"], 3), dtype=float)
    markers: dict[str, tuple[float, float]] = {}
    raw_markers = doc.data.get("markers") or {}
    if not isinstance(raw_markers, dict):
        raise doc.error(("markers",), "'markers' maps a name to [x, y]")
    for name, value in raw_markers.items():
        x, y = _numbers(doc, ("markers", name), value, 2)
        markers[str(name)] = (x, y)
    return World(name=str(doc.data.get("name") or path.stem), walls=_walls_array(walls),
                 starts=starts, border=border, markers=markers, source=str(path))


def _numbers(doc: YamlDoc, where: tuple, value, n: int, coordinates: int | None = None
             ) -> list[float]:
    """`n` finite numbers; the first `coordinates` of them (all by default) within
    COORDINATE (a pose's angle is not a coordinate)."""
    if not isinstance(value, list) or len(value) != n or not all(
            isinstance(v, (int, float)) and not isinstance(v, bool) for v in value):
        raise doc.error(where, f"expected a list of {n} numbers, got {value!r:.80}")
    if not all(math.isfinite(v) for v in value):
        raise doc.error(where, f"expected {n} finite numbers, got {value!r:.80}")
    for v in value[:n if coordinates is None else coordinates]:
        problem = COORDINATE.problem(v)
        if problem:
            raise doc.error(where, f"a coordinate {problem}")
    return [float(v) for v in value]


def _points(doc: YamlDoc, where: tuple, value, minimum: int) -> list[tuple[float, float]]:
    if not isinstance(value, list) or len(value) < minimum:
        raise doc.error(where, f"expected a list of at least {minimum} [x, y] points")
    pts = []
    for i, p in enumerate(value):
        x, y = _numbers(doc, where + (i,), p, 2)
        pts.append((x, y))
    return pts


def _walls_array(walls: list) -> np.ndarray:
    arr = np.array(walls, dtype=float).reshape(-1, 4)
    length = np.hypot(arr[:, 2] - arr[:, 0], arr[:, 3] - arr[:, 1])
    return arr[length > 1e-9]  # zero-length "walls" would only confuse the ray caster
