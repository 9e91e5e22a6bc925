"""Workload fairness (issue 50.5): the Gini coefficient against its definition, each robot's
share of a delivery run from a hand-made allocation log, its columns in results.csv and the
live view's idle line."""

import itertools
import random

import pytest

from mrta_zenoh.planning.fairness import gini
from mrta_delivery.metrics import Entry, fairness, workload


def pairwise(xs):
    """The definition: the mean absolute difference over all ordered pairs, halved, over the mean."""
    n, total = len(xs), sum(xs)
    return 0.0 if total == 0 else sum(abs(a - b) for a, b in itertools.product(xs, xs)) / (2 * n * total)


def test_gini_is_the_definition_and_its_extremes():
    rng = random.Random(50)
    for _ in range(200):
        xs = [rng.choice([0, 0, rng.random() * 10, rng.randint(0, 5)]) for _ in range(rng.randint(1, 9))]
        assert gini(xs) == pytest.approx(pairwise(xs), abs=1e-12)
    assert gini([3, 3, 3, 3]) == 0.0
    assert gini([0, 0, 0, 0, 7]) == pytest.approx(4 / 5)  # one robot did everything: (n − 1)/n
    assert gini([0, 0]) == 0.0  # nobody did anything: nobody was favoured
    with pytest.raises(ValueError):
        gini([1, -1])
    with pytest.raises(ValueError):
        gini([])


def test_each_robots_share_from_the_allocation_log():
    """robot1 serves t1 then t2 (a handed-over t3 it set off to too); robot2 served t3 after a
    handover; robot3 never moved. Busy time is the union of stretches from setting off to done
    (or the stretch's end), served counts each task's first completion once."""
    log = [Entry("t1", "robot1", 0.0, 10.0, started_at=0.0, done_at=10.0),
           Entry("t2", "robot1", 0.0, 18.0, started_at=10.0, done_at=18.0),
           Entry("t3", "robot1", 5.0, 12.0, started_at=8.0),          # overlaps: counted once
           Entry("t3", "robot2", 12.0, 30.0, started_at=12.0, done_at=25.0),
           Entry("t4", "robot2", 26.0, 40.0, started_at=26.0)]        # unfinished at the end
    shares = workload(["robot1", "robot2", "robot3"], log,
                      {"robot1": 4.0, "robot2": 6.5}, end=35.0)
    assert shares["robot1"] == {"served": 2, "busy": 18.0, "idle": 17.0, "distance": 4.0}
    assert shares["robot2"] == {"served": 1, "busy": 22.0, "idle": 13.0, "distance": 6.5}
    assert shares["robot3"] == {"served": 0, "busy": 0.0, "idle": 35.0, "distance": 0.0}
    f = fairness(shares)
    assert f["gini_served"] == pytest.approx(round(pairwise([2, 1, 0]), 4))
    assert f["gini_busy"] == pytest.approx(round(pairwise([18, 22, 0]), 4))
    assert f["gini_distance"] == pytest.approx(round(pairwise([4, 6.5, 0]), 4))


def test_the_gini_coefficients_are_results_columns_and_lower_is_better():
    from mrta_delivery.mission import DELIVERY, workload_lines
    from mrta_supervisor.mission.summary import MessageRates, Summary, flat_metrics
    metrics = {"completed": 1, **fairness({"robot1": {"served": 1, "busy": 5.0, "idle": 0.0,
                                                       "distance": 2.0},
                                            "robot2": {"served": 0, "busy": 0.0, "idle": 5.0,
                                                       "distance": 0.0}})}
    row = flat_metrics(Summary(
        mission="delivery", application="delivery_ssi", architecture="ssi", duration=60.0,
        speed=0.0, seed=1, wall_seconds=1.0, robots=["robot1", "robot2"],
        who_did_what={"robot1": [], "robot2": []}, first_full_allocation=None, coverage={},
        messages=MessageRates(1.0, 0.5, "ssi"), output="o", files=[], metrics=metrics))
    assert row["metrics.gini_served"] == 0.5 and row["metrics.gini_busy"] == 0.5
    assert "metrics.workload" not in row  # a JSON value, not a column
    assert all(DELIVERY.better[f"gini_{k}"] == "lower" for k in ("served", "busy", "distance"))
    assert "robot2 0 (0 s busy, 0 m)" in workload_lines(metrics)[0]


def test_the_live_view_says_who_is_idle():
    from rich.console import Console
    from mrta_supervisor.live.view import render
    snap = {"time": 20.0, "application": "Delivery", "architecture": "SSI",
            "robots": [{"id": "robot1", "state": "busy", "task": "t1", "since": 2.0},
                       {"id": "robot2", "state": "idle", "task": None, "since": 8.0}],
            "tasks": [{"id": "t1", "state": "allocated", "robots": ["robot1"]},
                      {"id": "t2", "state": "unallocated", "robots": []}],
            "alarms": [], "transitions": [],
            "ros2": {"nodes": [], "topics": [], "services": [], "tokens": 0, "max_tokens": 0,
                     "invalid_tokens": 0, "overflow": False, "domain": 0},
            "counts": {"samples": 0, "wrong_type": 0, "field_errors": 0}}
    console = Console(width=160, record=True)
    console.print(render(snap, 160))
    text = console.export_text()
    assert "idle: robot2 12s · 1 task(s) unallocated" in text
