"""Planning over ST-SR-TA problems (robots, point tasks, travel times): the problem model, route
timing and objectives, shortest paths around walls (pure Python, what agents use), and the
reference values a run is compared with (`reference.py`: the exact recursion, or OR-Tools
routing, loaded only where called)."""

from .problem import Point, Problem, Robot, Task, Windows, straight_line
from .reference import Reference, reference
from .schedule import (Evaluation, Objective, Visit, WindowCounts, check_routes, evaluate,
                       route_visits, routes_by_id, window_counts)

__all__ = ["Point", "Problem", "Robot", "Task", "Windows", "straight_line", "Evaluation",
           "Objective", "Visit", "WindowCounts", "check_routes", "evaluate", "route_visits",
           "routes_by_id", "window_counts", "Reference", "reference"]
