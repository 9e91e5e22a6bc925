"""Time windows end to end (issue 49.3): a generated windowed instance (hard windows on every
task) run by `mrta demo --instance` under each architecture — real processes, real Zenoh
sessions, the simulator — starts no service outside a task's window, serves some, and its
summary's window counts equal what its allocation records show (tests/test_windows.py's
re-statement) and are results.csv's `metrics.*` columns, and ends when nothing is left to serve.
The CI tier runs SSI's; the other five are `slow`."""

from __future__ import annotations


import pytest

from tests.test_windows import recomputed

pytestmark = pytest.mark.multiprocess

GENERATE = ["instance", "generate", "delivery", "--robots", "3", "--tasks", "4",
            "--capabilities", "", "--window-share", "1", "--window-width", "6", "15",
            "--window-slack", "0", "6", "--seed", "3"]
CI = "ssi"


@pytest.mark.timeout(600)
@pytest.mark.parametrize("arch", [pytest.param(a, marks=() if a == CI else pytest.mark.slow)
                                  for a in ("ssi", "alliance", "murdoch", "central", "cbba",
                                            "tessi")])
def test_a_windowed_run_serves_only_inside_windows_and_counts_them(children, tmp_path, arch):
    file = tmp_path / "tw.yaml"
    gen = children.mrta(*GENERATE, "-o", str(file), name="generate")
    assert gen.wait(60) == 0, gen.tail(10)
    out = tmp_path / arch
    s = children.demo(out, "--application", "delivery", "--instance", file, "--architecture",
                      arch, "--duration", "50", "--no-plots", quiet=True).summary(400)
    m = s["metrics"]
    assert m["windowed"] is True and s["instance"]["tasks"]["t1"]["due"] > 0
    assert m["late"] == 0 and m["early"] == 0, m           # hard windows: no violation
    assert m["served_in_window"] >= 1, m                  # not vacuous
    # every due is by 23 s: the run ends once nothing is left to serve (every task done or
    # missed), not at --duration, and says when (tests/test_windowed_run_end.py)
    assert s["ended_at"] is not None and s["recorded_until"] < 40, (s["ended_at"],
                                                                     s["recorded_until"])
    assert s["metrics"]["completed"] + m["missed"] == 4, m
    assert {k: m[k] for k in ("served_in_window", "missed", "late", "lateness", "early")} \
        == recomputed(s)
    from mrta_supervisor.mission.summary import flat_metrics, read_summary
    row = flat_metrics(read_summary(out / "summary.json"))  # results.csv's columns
    assert (row["metrics.served_in_window"], row["metrics.missed"]) == (m["served_in_window"],
                                                                        m["missed"])
    for record in s["allocation"]:                         # the records themselves
        task = s["instance"]["tasks"][record["task"]]
        if record.get("reached_at") is not None:   # a summary leaves out what is null
            assert task["earliest"] - 1e-3 <= record["reached_at"] <= task["due"] + 1e-3, record


@pytest.mark.slow
@pytest.mark.timeout(600)
def test_a_windowed_run_with_a_cancelled_task_ends_when_the_rest_is_over(children, tmp_path):
    """`mrta task cancel` as a summary replays it (the instance's `submitted`, through the run's
    intake): t4, whose window opens at 40 s, is cancelled at 1 s. The run ends once t1–t3 are
    done or missed (every due by 23 s), not at t4's due nor at --duration; t4 is neither served
    nor missed."""
    import yaml
    file = tmp_path / "tw.yaml"
    gen = children.mrta(*GENERATE, "-o", str(file), name="generate")
    assert gen.wait(60) == 0, gen.tail(10)
    doc = yaml.safe_load(file.read_text())
    doc["tasks"]["t4"].update(earliest=40.0, due=45.0)
    doc["submitted"] = [{"at": 1.0, "op": "cancel", "id": "t4"}]
    file.write_text(yaml.safe_dump(doc, sort_keys=False))
    out = tmp_path / "ssi"
    s = children.demo(out, "--application", "delivery", "--instance", file, "--architecture",
                      "ssi", "--duration", "60", "--no-plots", quiet=True).summary(400)
    m = s["metrics"]
    assert [r["state"] for r in s["tasks_at_run_time"]["tasks"]] == ["cancelled"], s
    assert s["ended_at"] is not None and s["ended_at"] < 30 and s["recorded_until"] < 40, \
        (s["ended_at"], s["recorded_until"])
    assert "t4" not in {r["task"] for r in s["allocation"] if r.get("done_at") is not None}
    assert m["completed"] + m["missed"] == 3, m             # t4: cancelled, not missed
