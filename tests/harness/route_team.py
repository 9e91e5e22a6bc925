"""A team of route-executing coordinators (SSI's, CBBA's) on an in-process message exchange and a
manual clock: what a robot says at tick t is heard by its teammates at their tick t + dt, as the
agent runtime delivers it in lockstep (sub-keyed kinds only to the robots whose `subjects`
name the sub-key); robots are bodies moving along their routes on the instance's travel model,
so a robot finishes a task exactly when the model says it reaches it and has served it
(quantised to the tick). A robot can crash (its token goes) or stall (it keeps talking, but
neither moves nor finishes anything from then on)."""

from __future__ import annotations

from mrta_zenoh.messages import Header
from mrta_zenoh.planning import Problem
from mrta_agent.route.own_route_params import OwnRouteParams, OwnRouteRobot

EPS = 1e-9


def params_for(problem: Problem, extra, progress_timeout: float = 10.0) -> OwnRouteParams:
    robot = OwnRouteRobot("", 10.0, 10.0, 1.0, progress_timeout, "odom", None, (), (), extra)
    return OwnRouteParams(robot, problem, {})


class Body:
    """A robot's `Readings`: it drives from where it last served (or its start) to the task it
    set off to, in the model's travel time, waits there for the task's window to open (as the
    delivery layer does) and serves it for the task's service time."""

    def __init__(self, team: "RouteTeam", robot_id: str):
        self.team, self.id = team, robot_id
        self.p = team.problem
        self.i = self.p.robot_index(robot_id)
        self.stalled_at: float | None = None
        self.frozen: tuple[float, float, float] | None = None

    def _leg(self):
        route = self.team.coords[self.id].route
        if route.current is None:
            return None
        src = self.p.task_index(route.served[-1].task) if route.served else None
        j = self.p.task_index(route.current)
        return src, j, route.since

    def _point(self, src):
        return self.p.robots[self.i].start if src is None else self.p.tasks[src].position

    def applicable(self, task_id: str, now: float) -> bool:
        return True

    def withdrawn(self, task_id: str, now: float) -> bool:
        return False  # nothing is cancelled at run time in these teams

    def done(self, task_id: str, now: float) -> bool:
        if self.stalled_at is not None and now >= self.stalled_at - EPS:
            return False
        leg = self._leg()
        if leg is None:
            return False
        src, j, since = leg
        task = self.p.tasks[j]
        return now >= max(since + self.p.travel(self.i, src, j), task.opens) + task.service - EPS

    def pose(self) -> tuple[float, float, float]:
        now = self.team.now
        if self.stalled_at is not None and now >= self.stalled_at - EPS:
            if self.frozen is None:
                self.frozen = self._pose(now)
            return self.frozen
        return self._pose(now)

    def _pose(self, now: float) -> tuple[float, float, float]:
        route = self.team.coords[self.id].route
        leg = self._leg()
        if leg is None:
            last = self.p.task_index(route.served[-1].task) if route.served else None
            return (*self._point(last), 0.0)
        src, j, since = leg
        a, b = self._point(src), self.p.tasks[j].position
        span = self.p.travel(self.i, src, j)
        f = 1.0 if span <= 0 else min(1.0, (now - since) / span)
        return (a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1]), 0.0)


class RouteTeam:
    def __init__(self, problem: Problem, messages: dict, make, dt: float = 0.1):
        """`make(robot_id, body)`: the robot's coordinator, reading `body`."""
        self.problem, self.messages, self.dt, self.now = problem, messages, dt, 0.0
        self.bodies = {r.id: Body(self, r.id) for r in problem.robots}
        self.coords = {r.id: make(r.id, self.bodies[r.id]) for r in problem.robots}
        self.inbox: dict[str, list] = {r: [] for r in self.coords}
        self.seq: dict[str, int] = {}
        self.sent: list[tuple[str, object]] = []
        for robot, coord in self.coords.items():
            for other in self.coords:
                if other != robot:
                    coord.teammate(other, True)

    def step(self) -> None:
        said = []
        for robot, coord in sorted(self.coords.items()):
            for kind, msg in self.inbox[robot]:
                coord.hear(kind, msg.header.frame_id, msg, msg.header.stamp)
            self.inbox[robot] = []
            for say in coord.tick(self.now):
                self.seq[robot] = self.seq.get(robot, 0) + 1
                msg = say.message(self.messages, Header(robot, self.now, self.seq[robot]))
                said.append((robot, say, msg))
        for robot, say, msg in said:
            self.sent.append((say.kind, msg))
            for other, coord in self.coords.items():
                if other == robot or say.kind not in coord.listens:
                    continue
                wanted = coord.subjects(say.kind)
                if wanted is not None and say.subkey not in wanted:
                    continue
                self.inbox[other].append((say.kind, msg))
        self.now = round(self.now + self.dt, 9)

    def served(self) -> dict[str, list[str]]:
        """Every robot's served tasks in order, crashed ones included."""
        return {r: c.route.served_ids() for r, c in self.all.items()}

    @property
    def all(self):
        return {**getattr(self, "_gone", {}), **self.coords}

    def run_until_served(self, limit: float = 300.0, after: float = 5.0) -> None:
        """Until every task is served and, for `after` seconds more, no live robot has a task
        left (a task served twice would be served in that time)."""
        everything = {t.id for t in self.problem.tasks}
        idle_since = None
        while self.now < limit:
            done = {t for tasks in self.served().values() for t in tasks} >= everything
            idle = done and not any(c.route.queue for c in self.coords.values())
            idle_since = (idle_since if idle_since is not None else self.now) if idle else None
            if idle_since is not None and self.now - idle_since >= after:
                return
            self.step()
        raise AssertionError(f"not every task served and the team idle by t={limit}: "
                             f"{self.served()}")

    def run_until(self, t: float) -> None:
        while self.now < t - EPS:
            self.step()

    def crash(self, robot: str) -> None:
        """`robot` stops dead: its token goes, nothing more from or to it."""
        self._gone = {**getattr(self, "_gone", {}), robot: self.coords.pop(robot)}
        del self.inbox[robot]
        for coord in self.coords.values():
            coord.teammate(robot, False)

    def stall(self, robot: str) -> None:
        self.bodies[robot].stalled_at = self.now
