"""Delivery instances as run input (docs/delivery.md, "Instances"): the document kind `mrta
instance show | validate` read, and the `delivery` generator (registered under
`mrta.instances`); the Solomon reader is `solomon.py`.

The generator draws from its own stream, `random.Random("mrta.instances/delivery/<seed>")` —
never the run's seed — and only through `random()` (whose sequence Python keeps fixed across
versions), rounding what it writes, so the same parameters and seed give the same file byte for
byte on any machine.
"""

from __future__ import annotations

import math
import random
from pathlib import Path
from typing import Annotated, Any

import msgspec

from mrta_zenoh.errors import ConfigError
from mrta_zenoh.instances import InstanceGenerator, InstanceKind
from mrta_zenoh.tasks.intake import Scheduled
from mrta_zenoh.tasks.messages import Op
from mrta_zenoh.yamlfile import YamlDoc
from mrta_zenoh.planning.geometry import CLEARANCE, point_segment_distance, segment_distance

from .instance import (InstanceDoc, admit_task, RobotSpec, TaskSpec, WorldSpec, document_data,
                       document_of, document_yaml)

WALL_GAP = 2 * CLEARANCE + 0.3   # m between walls: a corridor two robots' clearances wide
POINT_GAP = CLEARANCE + 0.2      # m from a start or task to any wall
START_GAP = 1.0                  # m between two robots' starts (robots are bodies)
TASK_GAP = 0.6                   # m between a task and any other start or task


def describe(doc: InstanceDoc, *, exact_limit: int, time_limit: float,
             solutions: int) -> dict[str, Any]:
    """Sizes, the travel-cost matrix's summary, the IA optimum and the reference values."""
    from mrta_zenoh.planning.assignment import ia_costs, optimal_assignment
    from mrta_zenoh.planning.reference import reference
    problem = doc.problem()
    cost = ia_costs(problem)
    finite = [float(c) for c in cost.flat if math.isfinite(c)]
    refs = {}
    for objective in ("minsum", "makespan", "flowtime"):
        ref = reference(problem, objective, exact_limit=exact_limit, time_limit=time_limit,
                        solutions=solutions)
        refs[objective] = {"value": round(ref.value, 3), "label": ref.label,
                           "method": ref.method, "seconds": round(ref.seconds, 3),
                           **({"stopped_by_time_limit": True} if ref.capped else {})}
    return {
        "robots": len(problem.robots), "tasks": len(problem.tasks),
        "online": problem.online,
        # a run shorter than this leaves tasks unserved (mrta demo's --duration defaults to 60 s)
        **({"last_arrival": round(max(t.arrival for t in problem.tasks), 3)}
           if problem.online else {}),
        **({"windows": {"kind": problem.windows.value,
                        "tasks": sum(t.windowed for t in problem.tasks)}}
           if problem.windowed else {}),
        "world": {"size": list(doc.world.size), "walls": len(doc.world.walls)},
        "cost_model": doc.travel_model(),
        "cost": {"min": round(min(finite), 3) if finite else None,
                 "mean": round(sum(finite) / len(finite), 3) if finite else None,
                 "max": round(max(finite), 3) if finite else None,
                 "incapable_pairs": cost.size - len(finite)},
        "ia_optimal_cost": round(optimal_assignment(cost).cost, 3),
        "reference": refs,
    }


class DeliveryKind(InstanceKind):
    application = "delivery"

    def load(self, doc: YamlDoc) -> InstanceDoc:
        return document_of(doc)

    def task_positions(self, doc: InstanceDoc) -> dict[str, tuple[float, float]]:
        return {tid: (float(t.position[0]), float(t.position[1]))
                for tid, t in doc.tasks.items()}

    def digest(self, doc: InstanceDoc) -> str:
        """The instance alone (InstanceDoc.body): where it came from (`generator`, a summary's
        `cost`) changes no index, so a run of a summary.json talks to one of its instance."""
        return super().digest(doc.body())

    def name(self, doc: InstanceDoc) -> str:
        return doc.name

    def robots(self, doc: InstanceDoc) -> list[str]:
        return list(doc.robots)

    def tasks(self, doc: InstanceDoc) -> list[str]:
        return list(doc.tasks)

    def describe(self, doc: InstanceDoc, *, exact_limit: int, time_limit: float,
                 solutions: int) -> dict[str, Any]:
        return describe(doc, exact_limit=exact_limit, time_limit=time_limit,
                        solutions=solutions)

    def problem(self, doc: InstanceDoc):
        return doc.problem()

    def admit(self, doc: InstanceDoc, task_id: str, fields: dict[str, Any]) -> None:
        admit_task(doc, task_id, fields)

    def grow(self, doc: InstanceDoc, task_id: str, fields: dict[str, Any],
             at: float) -> InstanceDoc:
        spec = msgspec.structs.replace(admit_task(doc, task_id, fields), arrival=at)
        return msgspec.structs.replace(doc, tasks={**doc.tasks, task_id: spec})

    def grown_problem(self, doc: InstanceDoc, before):
        return doc.grown_problem(before)

    def schedule(self, doc: InstanceDoc) -> list[Scheduled]:
        """A summary's `submitted`: each change at its instant, a task with its fields."""
        out = []
        for c in doc.submitted:
            fields = {} if c.task is None else {
                k: v for k, v in msgspec.to_builtins(c.task).items()
                if k != "arrival" and v is not None}
            out.append(Scheduled(c.at, Op(c.op), c.id, fields, c.priority, c.submitter))
        return out


KIND = DeliveryKind()


def document_text(doc: InstanceDoc, header: str) -> str:
    """The YAML of an instance document, after `header` (comment lines)."""
    return header + document_yaml({"application": KIND.application, **document_data(doc)})


def rounded(x: float, digits: int = 3) -> float:
    return round(x, digits) + 0.0  # + 0.0: no -0.0 in the file


def poisson_arrivals(rng: random.Random, rate: float, n: int) -> list[float]:
    """Arrival times of a Poisson process of `rate` tasks per second: n cumulative exponential
    gaps (inverse transform of `random()`), rounded to the millisecond."""
    t, out = 0.0, []
    for _ in range(n):
        t += -math.log(1.0 - rng.random()) / rate
        out.append(rounded(t))
    return out


def parse_mix(mix: str) -> list[tuple[str, float]]:
    """`lift:0.25,cold:0.25` → [(lift, 0.25), (cold, 0.25)] (probabilities summing to ≤ 1)."""
    out = []
    for item in filter(None, (s.strip() for s in mix.split(","))):
        name, sep, p = item.partition(":")
        try:
            prob = float(p)
        except ValueError:
            prob = math.nan
        if not sep or not name or not 0 <= prob <= 1:
            raise ConfigError(f"capability mix: {item!r} is not NAME:P with 0 ≤ P ≤ 1")
        out.append((name, prob))
    total = sum(p for _, p in out)
    if total > 1 and not math.isclose(total, 1.0):
        raise ConfigError(f"capability mix {mix!r}: the probabilities sum to more than 1")
    return out


class DeliveryGeneratorParams(msgspec.Struct, forbid_unknown_fields=True):
    robots: Annotated[int, msgspec.Meta(ge=1, le=200, description="Robots N.")] = 3
    tasks: Annotated[int, msgspec.Meta(ge=1, le=1000, description="Tasks M.")] = 5
    capabilities: Annotated[str, msgspec.Meta(
        description="Capability mix NAME:P,…: a task needs NAME with probability P; each robot "
                    "has each NAME with probability ½, the first robot has all.")] = \
        "lift:0.25,cold:0.25"
    speeds: Annotated[tuple[float, float], msgspec.Meta(
        description="Speed spread: robots' speeds uniform in [MIN, MAX] m/s.")] = (0.3, 0.7)
    service: Annotated[tuple[float, float], msgspec.Meta(
        description="Service times uniform in [MIN, MAX] s.")] = (2.0, 6.0)
    rate: Annotated[float, msgspec.Meta(
        ge=0.0, description="Arrivals: Poisson at RATE tasks/s; 0: all at 0.")] = 0.0
    room: Annotated[tuple[float, float], msgspec.Meta(
        description="Room WIDTH HEIGHT (m), centred on the origin.")] = (12.0, 8.0)
    walls: Annotated[int, msgspec.Meta(
        ge=0, le=50, description="Walls inside the room that robots drive around.")] = 0
    wall_length: Annotated[tuple[float, float], msgspec.Meta(
        description="Inner walls' lengths uniform in [MIN, MAX] m.")] = (2.0, 4.0)
    window_share: Annotated[float, msgspec.Meta(
        ge=0.0, le=1.0, description="Time windows: the share of tasks given one (Solomon's "
                                    "density); 0: none.")] = 0.0
    window_width: Annotated[tuple[float, float], msgspec.Meta(
        description="A window's width (due − earliest) uniform in [MIN, MAX] s: its "
                    "tightness.")] = (10.0, 30.0)
    window_slack: Annotated[tuple[float, float], msgspec.Meta(
        description="A window opens this long (uniform in [MIN, MAX] s) after the task could "
                    "first be reached: its arrival plus the fastest capable robot's travel from "
                    "its start.")] = (0.0, 10.0)
    windows: Annotated[str, msgspec.Meta(
        description="hard (a task not started by its due is missed) or soft (served "
                    "late).")] = "hard"


class DeliveryGenerator(InstanceGenerator):
    """Random delivery instances: robots, tasks, capabilities, speeds, arrivals, walls.

    Starts and tasks are uniform in the room, clear of every wall; walls have random
    orientations and leave corridors two robots' clearances wide."""

    name = "delivery"
    kind = KIND
    Params = DeliveryGeneratorParams

    def generate(self, params: DeliveryGeneratorParams, seed: int) -> str:
        doc = generate_document(params, seed)
        header = ("# A delivery instance (docs/delivery.md, \"Instances\"): `mrta instance "
                  "generate delivery` with the parameters under `generator`.\n")
        return document_text(doc, header)


def _check_ranges(p: DeliveryGeneratorParams) -> None:
    for name, (lo, hi), positive in (("speeds", p.speeds, True), ("service", p.service, False),
                                     ("wall-length", p.wall_length, True),
                                     ("window-width", p.window_width, False),
                                     ("window-slack", p.window_slack, False)):
        if not (math.isfinite(lo) and math.isfinite(hi) and lo <= hi
                and (lo > 0 if positive else lo >= 0)):
            raise ConfigError(f"--{name} {lo:g} {hi:g}: need {'0 <' if positive else '0 ≤'} "
                              "MIN ≤ MAX")
    if not 0.01 <= p.speeds[0] <= p.speeds[1] <= 100:
        raise ConfigError(f"--speeds {p.speeds[0]:g} {p.speeds[1]:g}: speeds are written to the "
                          "cm/s, so 0.01 ≤ MIN ≤ MAX ≤ 100 m/s")
    if p.windows not in ("hard", "soft"):
        raise ConfigError(f"--windows {p.windows}: hard or soft")
    if not all(math.isfinite(x) and 0 < x <= 10_000 for x in p.room):
        raise ConfigError(f"--room {p.room[0]:g} {p.room[1]:g}: need sizes in (0, 10000] m")


def _place_walls(rng: random.Random, p: DeliveryGeneratorParams) -> list[tuple]:
    w, h = p.room
    room = WorldSpec(size=(w, h)).all_walls()
    walls: list[tuple] = []
    for k in range(p.walls):
        for _ in range(1000):
            length = p.wall_length[0] + (p.wall_length[1] - p.wall_length[0]) * rng.random()
            angle = math.pi * rng.random()
            cx, cy = w * (rng.random() - 0.5), h * (rng.random() - 0.5)
            dx, dy = length / 2 * math.cos(angle), length / 2 * math.sin(angle)
            wall = (rounded(cx - dx), rounded(cy - dy), rounded(cx + dx), rounded(cy + dy))
            inside = max(abs(wall[0]), abs(wall[2])) < w / 2 and \
                max(abs(wall[1]), abs(wall[3])) < h / 2
            if inside and all(segment_distance(wall, o) >= WALL_GAP for o in room + walls):
                walls.append(wall)
                break
        else:
            raise ConfigError(f"could not place wall {k + 1} of {p.walls} in a {w:g} × {h:g} m "
                              f"room (walls keep {WALL_GAP:g} m apart): fewer --walls, a "
                              "bigger --room or shorter --wall-length")
    return walls


def _place_points(rng: random.Random, p: DeliveryGeneratorParams, walls: list[tuple],
                  count: int, taken: list[tuple[float, float]], gap: float, what: str
                  ) -> list[tuple[float, float]]:
    w, h = p.room
    every = WorldSpec(size=(w, h)).all_walls() + walls
    out = []
    for k in range(count):
        for _ in range(5000):
            pt = (rounded(w * (rng.random() - 0.5)), rounded(h * (rng.random() - 0.5)))
            if all(point_segment_distance(pt, x) >= POINT_GAP for x in every) \
                    and all(math.dist(pt, q) >= gap for q in taken + out):
                out.append(pt)
                break
        else:
            raise ConfigError(f"could not place {what} {k + 1} of {count} in a {w:g} × {h:g} m "
                              "room: fewer robots or tasks, or a bigger --room")
    return out


def generate_document(p: DeliveryGeneratorParams, seed: int) -> InstanceDoc:
    _check_ranges(p)
    mix = parse_mix(p.capabilities)
    rng = random.Random(f"mrta.instances/delivery/{seed}")
    walls = _place_walls(rng, p)
    starts = _place_points(rng, p, walls, p.robots, [], START_GAP, "robot")
    spots = _place_points(rng, p, walls, p.tasks, starts, TASK_GAP, "task")
    robots = {}
    for i, start in enumerate(starts):
        speed = rounded(p.speeds[0] + (p.speeds[1] - p.speeds[0]) * rng.random(), 2)
        caps = tuple(name for name, _ in mix if i == 0 or rng.random() < 0.5)
        robots[f"robot{i + 1}"] = RobotSpec(start, speed, caps)
    arrivals = (poisson_arrivals(rng, p.rate, p.tasks) if p.rate > 0 else [0.0] * p.tasks)
    tasks = {}
    for j, spot in enumerate(spots):
        u, need, acc = rng.random(), "", 0.0
        for name, prob in mix:
            acc += prob
            if u < acc:
                need = name
                break
        service = rounded(p.service[0] + (p.service[1] - p.service[0]) * rng.random(), 1)
        tasks[f"t{j + 1}"] = TaskSpec(spot, arrivals[j], service, need)
    source = {"name": "delivery", "seed": seed, **msgspec.to_builtins(p)}
    if not p.window_share:  # no windows: the file (its `generator` too) is what it was before
        for key in WINDOW_PARAMS:
            source.pop(key)
    for key, value in source.items():
        if isinstance(value, tuple):
            source[key] = list(value)
    # walls and windows in the name: the same sizes and seed with and without them differ
    walled = f"-w{p.walls}" if p.walls else ""
    windowed = f"-tw{round(100 * p.window_share)}" if p.window_share else ""
    doc = InstanceDoc(robots, tasks, WorldSpec(tuple(p.room), tuple(walls)),
                      f"delivery-r{p.robots}-t{p.tasks}{walled}{windowed}-{seed}",
                      generator=source, windows=p.windows)
    doc.check()
    problem = doc.problem()  # every task reachable: a ConfigError now rather than at the run
    if p.window_share:
        doc = with_windows(doc, problem, p, seed)
    return doc


WINDOW_PARAMS = ("window_share", "window_width", "window_slack", "windows")


def with_windows(doc: InstanceDoc, problem, p: DeliveryGeneratorParams,
                 seed: int) -> InstanceDoc:
    """`doc` with a window on each task drawn with probability `window_share` (docs/delivery.md,
    "Instances"): it opens `window_slack` after the task could first be reached — its arrival
    plus the fastest capable robot's travel from its own start — and stays open
    `window_width`. Drawn from a stream of their own
    (`mrta.instances/delivery/<seed>/windows`), so the rest of the instance is the one the
    same seed gives without windows."""
    rng = random.Random(f"mrta.instances/delivery/{seed}/windows")
    tasks = {}
    for j, (tid, spec) in enumerate(doc.tasks.items()):
        draws = [rng.random() for _ in range(3)]  # always three: a task's draws do not
        if draws[0] >= p.window_share:           # depend on whether the last had a window
            tasks[tid] = spec
            continue
        reach = min(problem.travel(i, None, j) for i in range(len(problem.robots))
                    if problem.capable(i, j))
        slack = p.window_slack[0] + (p.window_slack[1] - p.window_slack[0]) * draws[1]
        width = p.window_width[0] + (p.window_width[1] - p.window_width[0]) * draws[2]
        earliest = rounded(spec.arrival + reach + slack, 1)
        tasks[tid] = msgspec.structs.replace(spec, earliest=earliest,
                                             due=rounded(earliest + width, 1))
    return msgspec.structs.replace(doc, tasks=tasks)


GENERATOR = DeliveryGenerator()
