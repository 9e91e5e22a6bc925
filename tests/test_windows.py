"""Time windows (issue 49.1; docs/delivery.md, "Time windows"): a task's `earliest` and `due` in
the instance document (strict, bounded, in the digest, absent from today's files), route timing
that waits for `earliest`, and the window counts — served in window, missed, late, lateness,
early — defined once (`planning.schedule.window_counts`) and recomputed here from a summary's
allocation records by a direct re-statement of the definitions."""

from __future__ import annotations

import math
import re

import pytest
from click.testing import CliRunner
from hypothesis import given, settings, strategies as st

from mrta_delivery.instance import document_data, load_document
from mrta_delivery.instances import KIND
from mrta_delivery.metrics import Entry
from mrta_delivery.objectives import service_starts, window_metrics
from mrta_zenoh.cli.main import cli
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.planning import (Problem, Robot, Task, Windows, evaluate, route_visits,
                                 window_counts)
from mrta_zenoh.yamlfile import load_yaml

ROBOT = "robots:\n  robot1: {start: [0, 0], speed: 0.5}\n"


def line_task(**window) -> Problem:
    """One robot at the origin (1 m/s), tasks 2 m apart on a line, 1 s of service each."""
    return Problem((Robot("r", (0.0, 0.0), 1.0),),
                   (Task("a", (2.0, 0.0), service=1.0, **window),
                    Task("b", (4.0, 0.0), service=1.0)))


def test_a_route_waits_for_earliest_and_counts_a_late_start():
    p = line_task(earliest=5.0, due=6.0)
    a, b = route_visits(p, 0, [0, 1])
    assert (a.reach, a.start, a.end) == (2.0, 5.0, 6.0)   # there at 2, waits until 5
    assert (b.reach, b.start) == (8.0, 8.0)
    assert evaluate(p, {0: [0, 1]}).windows.to_json() == {
        "served_in_window": 2, "missed": 0, "late": 0, "lateness": 0.0, "early": 0}
    late = line_task(due=1.0)                             # reached at 2: one second late
    counts = evaluate(late, {0: [0, 1]}).windows
    assert (counts.served_in_window, counts.late, counts.lateness, counts.violations) == \
        (1, 1, 1.0, 1)


def test_missed_is_a_task_not_served_whose_due_passed_by_the_end():
    p = line_task(due=3.0)
    assert window_counts(p, {}).missed == 1               # a plan has no end
    assert window_counts(p, {}, end=2.0).missed == 0      # its due is still to come
    assert window_counts(p, {}, end=3.5).missed == 1
    assert window_counts(p, {1: 7.0}).missed == 1          # b (no due) is never missed
    assert window_counts(p, {0: 1.0}).early == 0           # no earliest: never early
    assert window_counts(line_task(earliest=2.0), {0: 1.0}).early == 1


def test_a_problem_refuses_a_window_that_could_never_open():
    with pytest.raises(ConfigError, match="due"):
        line_task(earliest=5.0, due=4.0)
    with pytest.raises(ConfigError, match="due"):
        Problem((), (Task("t", (0, 0), arrival=9.0, due=8.0),))
    with pytest.raises(ConfigError, match="earliest"):
        Problem((), (Task("t", (0, 0), earliest=math.nan),))
    with pytest.raises(ValueError):
        Problem((), (), windows="firm")
    assert Problem((), (), windows="soft").windows is Windows.SOFT


def doc_of(tmp_path, text: str):
    f = tmp_path / "i.yaml"
    f.write_text(text)
    return load_document(f)


def test_the_document_carries_windows_into_the_problem(tmp_path):
    doc = doc_of(tmp_path, ROBOT + "tasks:\n  t1: {position: [1, 1], earliest: 4, due: 9.5}\n"
                 "  t2: {position: [2, 1]}\nwindows: soft\n")
    p = doc.problem()
    assert (p.tasks[0].earliest, p.tasks[0].due) == (4.0, 9.5)
    assert (p.tasks[1].earliest, p.tasks[1].due) == (0.0, math.inf)
    assert p.windows is Windows.SOFT and p.windowed
    assert document_data(doc.body())["windows"] == "soft"


def test_todays_files_stay_as_they_are_and_the_digest_covers_windows(tmp_path):
    plain = doc_of(tmp_path, ROBOT + "tasks:\n  t1: {position: [1, 1]}\n")
    data = document_data(plain.body())
    assert "windows" not in data and set(data["tasks"]["t1"]) == {
        "position", "arrival", "service", "capability", "reward"}
    assert plain.windows == "hard" and not plain.problem().windowed
    digests = {KIND.digest(doc_of(tmp_path, ROBOT + "tasks:\n  t1: {position: [1, 1]" + extra))
               for extra in ("}\n", ", due: 9}\n", ", due: 9}\nwindows: soft\n",
                             ", earliest: 1, due: 9}\n")}
    assert len(digests) == 4


BAD = [
    (ROBOT + "tasks:\n  t1: {position: [1, 1], earliest: 5, due: 4}\n", 4, "tasks/t1/due",
     "before the task may start (5 s)"),
    (ROBOT + "tasks:\n  t1: {position: [1, 1], arrival: 6, due: 4}\n", 4, "tasks/t1/due",
     "before the task arrives (6 s)"),
    (ROBOT + "tasks:\n  t1: {position: [1, 1], earliest: -1}\n", 4, "tasks/t1/earliest",
     "Expected float >= 0.0"),
    (ROBOT + "tasks:\n  t1: {position: [1, 1], earlist: 1}\n", 4, "tasks/t1/earlist",
     "did you mean 'earliest'?"),
    (ROBOT + "tasks:\n  t1: {position: [1, 1], due: .inf}\n", 4, "tasks/t1/due", "expected a finite number"),
    (ROBOT + "windows: firm\n", 3, "windows", "Invalid enum value 'firm'"),
]


@pytest.mark.parametrize("text, line, key, message", BAD)
def test_a_bad_window_exits_2_naming_file_line_and_key(tmp_path, text, line, key, message):
    f = tmp_path / "bad.yaml"
    f.write_text(text)
    r = CliRunner().invoke(cli, ["instance", "validate", str(f)])
    assert r.exit_code == 2, r.output
    first = r.output.strip().splitlines()
    assert len(first) == 1 and "Traceback" not in r.output
    assert re.search(rf"{re.escape(str(f))}:{line}: '{re.escape(key)}': .*{re.escape(message)}",
                     first[0]), first[0]


# --- recomputed from a summary's allocation records -------------------------------------------

def recomputed(summary: dict) -> dict:
    """The window counts of a summary, from its `instance` and `allocation` sections and its end
    alone, restating docs/delivery.md's definitions without the code under test."""
    tasks = summary["instance"]["tasks"]
    end = summary["ended_at"] if summary.get("ended_at") is not None else summary["duration"]
    first: dict[str, dict] = {}
    for r in summary["allocation"]:
        if r["done_at"] is not None and (r["task"] not in first
                                         or r["done_at"] < first[r["task"]]["done_at"]):
            first[r["task"]] = r
    out = {"served_in_window": 0, "missed": 0, "late": 0, "lateness": 0.0, "early": 0}
    for tid, t in tasks.items():
        due = t.get("due", math.inf)
        if tid not in first:
            out["missed"] += due <= end  # by the end: a run may end on a missed due
            continue
        r = first[tid]
        start = r.get("reached_at")  # a summary leaves out what is null
        start = start if start is not None else r["done_at"] - t["service"]
        if start < t.get("earliest", 0.0) - 1e-3:
            out["early"] += 1
        elif start > due + 1e-3:
            out["late"] += 1
            out["lateness"] += start - due
        else:
            out["served_in_window"] += 1
    out["lateness"] = round(out["lateness"], 3)
    return out


windows = st.tuples(st.floats(0, 20), st.floats(0, 20)).map(sorted)
record = st.tuples(st.integers(0, 3), st.sampled_from(["r1", "r2"]), st.floats(0, 40),
                   st.booleans(), st.booleans())


@settings(max_examples=80, derandomize=True, deadline=None)
@given(st.lists(st.tuples(windows, st.booleans()), min_size=4, max_size=4),
       st.lists(record, max_size=8), st.floats(5, 60))
def test_the_counts_are_what_the_allocation_records_show(tasks, records, end):
    """Forged summaries (any windows, any records, a completion or none, a `started` event or
    none): the metrics' counts equal the re-statement's."""
    specs = {f"t{k}": {"position": [k, 0.0], "arrival": 0.0, "service": 2.0,
                       **({"earliest": lo, "due": hi} if windowed else {})}
             for k, ((lo, hi), windowed) in enumerate(tasks)}
    log = [Entry(f"t{k}", robot, 0.0, reached + 2.0 + 5, reached, reached + 2.0 if done else None,
                 reached if seen else None)
           for k, robot, reached, done, seen in records]
    summary = {"instance": {"tasks": specs}, "allocation": [e.to_json() for e in log],
               "ended_at": None, "duration": end}
    problem = Problem((Robot("r1", (0, 0), 1.0), Robot("r2", (1, 0), 1.0)),
                      tuple(Task(tid, tuple(s["position"]), service=2.0,
                                 earliest=s.get("earliest", 0.0), due=s.get("due", math.inf))
                            for tid, s in specs.items()))
    assert window_metrics(problem, log, end) == recomputed(summary)
    assert set(service_starts(problem, log)) == {problem.task_index(e.task) for e in log
                                                 if e.done_at is not None}


def test_the_metrics_registry_gives_window_columns(tmp_path):
    """The counts are `metrics.*` columns of results.csv like every delivery metric."""
    from mrta_delivery.metrics import analyse
    from mrta_zenoh.architectures import architecture
    doc = doc_of(tmp_path, ROBOT + "tasks:\n  t1: {position: [1, 1], due: 3}\n")
    a = analyse([], architecture("alliance"), doc.body(), 10.0)
    assert a.metrics["windowed"] is True
    assert {k: a.metrics[k] for k in ("served_in_window", "missed", "late", "lateness",
                                      "early")} == {"served_in_window": 0, "missed": 1,
                                                    "late": 0, "lateness": 0.0, "early": 0}


def test_each_row_has_its_gap_to_the_hindsight_reference(tmp_path):
    """`reference_served_in_window`: the most tasks any plan serves in window (brute force over
    every order of one robot here), not the instance's task count; `served_gap` what the run
    served in window short of it; proven only for an exact reference."""
    from itertools import permutations

    from mrta_delivery.metrics import analyse
    from mrta_zenoh.architectures import architecture
    doc = doc_of(tmp_path, ROBOT + "tasks:\n  t1: {position: [1, 1], due: 3}\n"
                 "  t2: {position: [-1, 1], due: 3}\n  t3: {position: [0, 2], earliest: 4, "
                 "due: 9}\n  t4: {position: [5, 0], due: 2}\n")
    problem = doc.body().problem()
    best = max(evaluate(problem, {0: list(order[:k])}).windows.served_in_window
               for order in permutations(range(4)) for k in range(5))
    assert best == 2 < len(problem.tasks)  # t1 or t2 (not both), then t3; t4 never
    a = analyse([], architecture("alliance"), doc.body(), 10.0)
    assert {k: a.metrics[k] for k in ("reference_served_in_window", "reference_served_proven",
                                      "served_gap")} == {"reference_served_in_window": best,
                                                         "reference_served_proven": True,
                                                         "served_gap": best}
    from mrta_delivery.objectives import references, reference_window_metrics
    assert reference_window_metrics(problem, references(problem), 1)["served_gap"] == 1
    plain = doc_of(tmp_path, ROBOT + "tasks:\n  t1: {position: [1, 1]}\n").body()
    assert analyse([], architecture("alliance"), plain, 10.0).metrics["served_gap"] is None


def test_a_windowed_instance_checks_loaded_through_the_yaml_reader(tmp_path):
    f = tmp_path / "i.yaml"
    f.write_text(ROBOT + "tasks:\n  t1: {position: [1, 1], earliest: 2, due: 2}\n")
    assert KIND.load(load_yaml(f)).tasks["t1"].due == 2.0   # a window of one instant is fine


# --- generated windows --------------------------------------------------------------------------

def generated(tmp_path, name, *args):
    out = tmp_path / name
    r = CliRunner().invoke(cli, ["instance", "generate", "delivery", "--robots", "3",
                                 "--tasks", "8", "--seed", "4", *args, "-o", str(out)],
                           catch_exceptions=False)
    assert r.exit_code == 0, r.output
    return out


def test_generated_windows_are_seeded_bounded_and_leave_the_rest_of_the_instance(tmp_path):
    plain = load_document(generated(tmp_path, "plain.yaml"))
    args = ("--window-share", "0.5", "--window-width", "5", "15", "--window-slack", "1", "3",
            "--windows", "soft")
    a = generated(tmp_path, "a.yaml", *args)
    assert a.read_bytes() == generated(tmp_path, "b.yaml", *args).read_bytes()
    doc = load_document(a)
    assert doc.name == "delivery-r3-t8-tw50-4" and doc.windows == "soft"
    assert "window_share" not in plain.generator and doc.generator["window_share"] == 0.5
    p = doc.problem()
    windowed = [j for j, t in enumerate(p.tasks) if t.windowed]
    assert 0 < len(windowed) < len(p.tasks)
    for j, t in enumerate(p.tasks):
        same = plain.tasks[t.id]
        assert (same.position, same.arrival, same.service) == (doc.tasks[t.id].position,
                                                               t.arrival, t.service)
        if j in windowed:  # opens slack after the fastest capable robot could be there
            reach = min(p.travel(i, None, j) for i in range(3) if p.capable(i, j))
            assert 1.0 - 0.06 <= t.earliest - t.arrival - reach <= 3.0 + 0.06
            assert 5.0 - 0.1 <= t.due - t.earliest <= 15.0 + 0.1
    r = CliRunner().invoke(cli, ["instance", "generate", "delivery", "--windows", "firm"])
    assert r.exit_code == 2 and "--windows firm" in r.output
