"""What a study needs from every run lands in results.csv as *measured* columns: coordination
messages by kind, when the run ended, the decisions and their computation time. A column the
results reader took for a parameter would split an experiment's cells by its value (the
README's experiment table once grew a cell per coordination count)."""

from __future__ import annotations

from mrta_supervisor.mission import summary as summary_module
from mrta_supervisor.experiment.results import kind
from mrta_supervisor.mission.summary import Decisions, Summary, flat_metrics


def test_a_runs_record_columns_are_measures_not_parameters():
    s = Summary(mission="delivery", application="delivery_central", architecture="central",
                duration=60.0, speed=0.0, seed=1, wall_seconds=1.0, robots=["robot1"],
                who_did_what={"robot1": []}, first_full_allocation=None, coverage={},
                messages=summary_module.MessageRates(1.0, 0.5, "central",
                                                     by_kind={"queue": 7, "progress": 9}),
                output="o", files=[], ended_at=33.5,
                decisions=Decisions(4, 0.8, 20.0, "minsum"))
    row = flat_metrics(s)
    added = {"messages.queue": 7, "messages.progress": 9, "ended_at": 33.5, "decisions": 4,
             "decision_ms_median": 0.8, "decision_ms_max": 20.0}
    assert {k: row[k] for k in added} == added
    assert {k: kind(k) for k in added} == dict.fromkeys(added, "measure")
