"""Solomon-format VRPTW files as delivery instances: read by `vrplib` (the format's maintained
reader, PyPI), mapped as docs/delivery.md ("Solomon files") says, registered under
`mrta.instances` as `solomon`:

    mrta instance generate solomon --file C101.txt --robots 3 --tasks 10 -o c101.yaml

* the depot → the robots' starts (robots are bodies, so they stand on a circle around it, at
  least `START_GAP` apart; one robot stands on it);
* customers 1…M (file order) → tasks `c<number>`: position, service time, due date → `due`, and
  ready time → `earliest` on a task known from the start (the VRPTW's own reading: customers
  are known, their windows open later) — or, with `--ready arrival`, → `arrival` (the task
  unknown until then: an online variant, what this reader did before windows);
* coordinates scaled into the room (centred, 1 m from its walls): one factor s for both axes;
* time: Solomon's vehicles cover one distance unit per time unit. A robot covers s metres in
  s / v seconds at speed v, so every time (ready, due, service) is multiplied by s / v: the
  instance keeps its time structure — who can reach what before it is ready or due.
* demand and capacity are dropped (the delivery model has no loads); the fleet is homogeneous
  (`--speed`), with no capabilities.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated

import msgspec

from mrta_zenoh.errors import ConfigError
from mrta_zenoh.instances import InstanceGenerator
from mrta_zenoh.yamlfile import read_bounded

from .instance import InstanceDoc, RobotSpec, TaskSpec, WorldSpec
from .instances import KIND, POINT_GAP, START_GAP, document_text, rounded

MARGIN = 1.0  # m between the scaled points' box and the room's walls
READY = ("earliest", "arrival")
WINDOWS = ("hard", "soft")


class SolomonParams(msgspec.Struct, forbid_unknown_fields=True):
    file: Annotated[str, msgspec.Meta(description="The Solomon-format file to read.")]
    robots: Annotated[int, msgspec.Meta(ge=1, le=200, description="Robots N (at the depot); "
                                        "0 < N.")] = 3
    tasks: Annotated[int, msgspec.Meta(ge=0, description="The first M customers; 0: all.")] = 0
    room: Annotated[tuple[float, float], msgspec.Meta(
        description="Room WIDTH HEIGHT (m) the coordinates are scaled into.")] = (12.0, 8.0)
    speed: Annotated[float, msgspec.Meta(gt=0, le=100,
                                         description="Every robot's speed (m/s).")] = 0.5
    ready: Annotated[str, msgspec.Meta(
        description="What a customer's ready time becomes: earliest (its window opens; the "
                    "task is known from the start) or arrival (the task appears then: "
                    "online).")] = "earliest"
    windows: Annotated[str, msgspec.Meta(
        description="hard (a task not started by its due is missed) or soft (served "
                    "late).")] = "hard"


def _read(path: str):
    import vrplib
    _check_numbers(path)
    try:
        return vrplib.read_instance(path, instance_format="solomon")
    except FileNotFoundError:
        raise ConfigError("no such file", file=path) from None
    except (ValueError, IndexError, KeyError, RuntimeError) as exc:
        raise ConfigError(f"not a Solomon-format instance ({exc})", file=path) from None


def _check_numbers(path: str) -> None:
    """Every value of the customer table a finite number (ConfigError naming file and line):
    vrplib reads `nan` into an integer table as a plausible coordinate (-1), and `inf` or 1e308
    would scale every point to nothing."""
    lines = read_bounded(Path(path), "a Solomon file").decode("utf-8", "replace").splitlines()
    header = next((n for n, line in enumerate(lines) if line.split()[:2] == ["CUST", "NO."]),
                  None)
    for n, line in enumerate(lines[header + 1:] if header is not None else [],
                             start=(header or 0) + 2):
        for value in line.split():
            try:
                x = float(value)
            except ValueError:
                x = math.nan
            if not (math.isfinite(x) and abs(x) <= 1e9):
                raise ConfigError(f"{value!r:.20} is not a finite number up to 1e9 (a Solomon "
                                  "file's customer table holds numbers only)", file=path, line=n)


def solomon_document(p: SolomonParams) -> InstanceDoc:
    for flag, value, allowed in (("ready", p.ready, READY), ("windows", p.windows, WINDOWS)):
        if value not in allowed:
            raise ConfigError(f"--{flag} {value}: one of {', '.join(allowed)}")
    data = _read(p.file)
    coords = [tuple(map(float, xy)) for xy in data["node_coord"]]
    windows = [tuple(map(float, w)) for w in data["time_window"]]
    service = [float(s) for s in data["service_time"]]
    customers = list(range(1, len(coords)))
    if p.tasks:
        if p.tasks > len(customers):
            raise ConfigError(f"--tasks {p.tasks}: the file has {len(customers)} customers",
                              file=p.file)
        customers = customers[:p.tasks]
    used = [0] + customers
    xs, ys = [coords[k][0] for k in used], [coords[k][1] for k in used]
    w, h = p.room
    span_x, span_y = max(xs) - min(xs), max(ys) - min(ys)
    room_x, room_y = w - 2 * MARGIN, h - 2 * MARGIN
    if room_x <= 0 or room_y <= 0:
        raise ConfigError(f"--room {w:g} {h:g}: too small (the points keep {MARGIN:g} m from "
                          "the walls)")
    scale = min(room_x / span_x if span_x else math.inf, room_y / span_y if span_y else math.inf)
    scale = 1.0 if not math.isfinite(scale) else scale
    cx, cy = (max(xs) + min(xs)) / 2, (max(ys) + min(ys)) / 2
    ring = 0.0 if p.robots == 1 else max(START_GAP, START_GAP * p.robots / (2 * math.pi))
    ring_at = [(0.0, 0.0)] + [(ring * math.cos(2 * math.pi * i / p.robots),
                               ring * math.sin(2 * math.pi * i / p.robots))
                              for i in range(1, p.robots)]
    scale = _depot_scale(scale, (coords[0][0] - cx, coords[0][1] - cy), ring_at, (w, h))

    def place(k: int) -> tuple[float, float]:
        return (rounded((coords[k][0] - cx) * scale), rounded((coords[k][1] - cy) * scale))

    times = scale / p.speed  # s per Solomon time unit
    depot = place(0)
    robots = {}
    for i, (ox, oy) in enumerate(ring_at):
        start = (rounded(depot[0] + ox) if i else depot[0],
                 rounded(depot[1] + oy) if i else depot[1])
        robots[f"robot{i + 1}"] = RobotSpec(start, p.speed)
    tasks = {}
    for k in customers:
        ready = rounded(windows[k][0] * times)
        tasks[f"c{k}"] = TaskSpec(place(k), ready if p.ready == "arrival" else 0.0,
                                  rounded(service[k] * times),
                                  earliest=ready if p.ready == "earliest" and ready else None,
                                  due=rounded(windows[k][1] * times))
    online = "-online" if p.ready == "arrival" else ""
    name = f"{data.get('name') or 'solomon'}-r{p.robots}-t{len(customers)}{online}"
    doc = InstanceDoc(robots, tasks, WorldSpec((w, h)), name,
                      generator={"name": "solomon", "file": p.file.rsplit("/", 1)[-1],
                                 "robots": p.robots, "tasks": p.tasks, "room": [w, h],
                                 "speed": p.speed, "ready": p.ready, "windows": p.windows,
                                 "scale_m_per_unit": rounded(scale, 6),
                                 "seconds_per_unit": rounded(times, 6)},
                      windows=p.windows)
    doc.check()
    return doc


def _depot_scale(scale: float, depot: tuple[float, float], ring_at: list[tuple[float, float]],
                 room: tuple[float, float]) -> float:
    """`scale`, lowered where a robot on the ring round the depot would stand closer than
    POINT_GAP to a wall (a depot at the edge of the customers' box: the margin alone does not
    hold the ring — a robot inside the wall's margin, refused by validate)."""
    for ox, oy in ring_at:
        for d, o, size in ((depot[0], ox, room[0]), (depot[1], oy, room[1])):
            limit = size / 2 - POINT_GAP  # how far from the centre a start may stand
            if abs(o) > limit:
                raise ConfigError(f"--room {room[0]:g} {room[1]:g}: too small for "
                                  f"{len(ring_at)} robots round the depot (they stand "
                                  f"{START_GAP:g} m apart, {POINT_GAP:g} m from the walls)")
            if d:
                scale = min(scale, ((limit if d > 0 else -limit) - o) / d)
    if scale <= 0:
        raise ConfigError(f"--room {room[0]:g} {room[1]:g}: too small for {len(ring_at)} robots "
                          "round the depot")
    return scale


class SolomonGenerator(InstanceGenerator):
    """Delivery instances from a Solomon-format VRPTW file (read by vrplib).

    The depot holds the robots' starts, customers become tasks (ready time → earliest, or
    arrival with `--ready arrival`; service time; due date → due), coordinates and times scaled
    into the room (docs/delivery.md)."""

    name = "solomon"
    kind = KIND
    Params = SolomonParams

    def generate(self, params: SolomonParams, seed: int) -> str:
        header = ("# A delivery instance from a Solomon-format file (docs/delivery.md, \"Solomon "
                  "files\"): `mrta instance generate solomon`.\n")
        return document_text(solomon_document(params), header)


GENERATOR = SolomonGenerator()
