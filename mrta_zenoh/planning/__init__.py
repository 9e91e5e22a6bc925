"""Planning over ST-SR-TA problems (robots, point tasks, travel times): the problem model, route
timing and objectives (pure Python, what agents use), and the reference solvers a run is compared
with (which load scipy or a routing solver, and only where they are called)."""

from .problem import Point, Problem, Robot, Task, straight_line
from .schedule import Evaluation, Objective, Visit, check_routes, evaluate, route_visits, routes_by_id

__all__ = ["Point", "Problem", "Robot", "Task", "straight_line", "Evaluation", "Objective", "Visit",
           "check_routes", "evaluate", "route_visits", "routes_by_id"]
