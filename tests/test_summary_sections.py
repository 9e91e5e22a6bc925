"""Summaries an application extends: the framework's summary schema names no application
section; an application's sections are its own type, declared by its Mission, written at the
top level of summary.json and validated by that type when read back; older summaries still
read, or fail saying why."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import msgspec
import pytest

from mrta_zenoh.errors import ConfigError
from mrta_supervisor.mission import summary as summary_module
from mrta_supervisor.mission.summary import (FRAMEWORK_KEYS, Summary, SummarySections, checked_sections,
                                     check_sections_type, read_summary, summary_json,
                                     write_summary)

DATA = Path(__file__).parent / "data" / "summaries"


def test_the_framework_schema_names_no_application_section():
    assert not {"instance", "allocation"} & FRAMEWORK_KEYS
    assert not {"instance", "allocation"} & set(Summary.__struct_fields__)


class PingSections(SummarySections):
    pings: list[int]
    peer: str


class PingMission:
    summary_sections = PingSections
    better: dict = {}


def summary(**kw) -> Summary:
    base = dict(mission="ping", application="ping_app", architecture="alliance", duration=10.0,
                speed=0.0, seed=1, wall_seconds=1.0, robots=["robot1"],
                who_did_what={"robot1": []}, first_full_allocation=None, coverage={},
                messages=summary_module.MessageRates(1.0, 0.5, "alliance"), output="o",
                files=[])
    base.update(kw)
    return Summary(**base)


def test_a_third_party_section_round_trips_at_the_top_level_validated_by_its_own_type(
        tmp_path, monkeypatch):
    monkeypatch.setattr(summary_module, "mission_hook",
                        lambda name: PingMission if name == "ping" else None)
    s = summary(sections=PingSections(pings=[1, 2, 3], peer="robot2"))
    write_summary(tmp_path / "summary.json", s)
    data = json.loads((tmp_path / "summary.json").read_text())
    assert data["pings"] == [1, 2, 3] and data["peer"] == "robot2" and "sections" not in data
    back = read_summary(tmp_path / "summary.json")
    assert back.sections == PingSections(pings=[1, 2, 3], peer="robot2") and back == s
    # the application's type checks its section when it is read back
    data["pings"] = ["x"]
    (tmp_path / "bad.json").write_text(json.dumps(data))
    with pytest.raises(ConfigError, match=r"bad.json: mission 'ping'.s sections: Expected `int`"):
        read_summary(tmp_path / "bad.json")
    data["pings"], data["pingz"] = [1], 3
    (tmp_path / "bad.json").write_text(json.dumps(data))
    with pytest.raises(ConfigError, match="unknown field `pingz`"):
        read_summary(tmp_path / "bad.json")


def test_a_section_no_mission_declares_is_refused_with_a_did_you_mean(tmp_path):
    data = json.loads((DATA / "patrol_schema2.json").read_text())
    data["lockstep_exac"] = True  # patrol declares no sections: a typo of a framework field
    (tmp_path / "s.json").write_text(json.dumps(data))
    with pytest.raises(ConfigError, match=r"s.json: unknown field 'lockstep_exac': mission "
                                          r"'patrol' declares no summary sections \(did you "
                                          r"mean 'lockstep_exact'\?\)"):
        read_summary(tmp_path / "s.json")
    data.pop("lockstep_exac")
    data.update(mission="nowhere", extra=1)
    (tmp_path / "s.json").write_text(json.dumps(data))
    with pytest.raises(ConfigError, match="mission 'nowhere' is not installed here"):
        read_summary(tmp_path / "s.json")


def test_an_old_patrol_summary_reads_and_is_written_back_without_the_null_sections(tmp_path):
    """Schema 2 had `instance` and `allocation` as framework fields, null but for delivery."""
    s = read_summary(DATA / "patrol_schema2.json")
    assert s.sections is None and s.failure.takeover_seconds == 3.6 and s.schema == 3
    shutil.copy(DATA / "patrol_schema2.json", tmp_path / "summary.json")
    write_summary(tmp_path / "summary.json", s)
    data = json.loads((tmp_path / "summary.json").read_text())
    assert "instance" not in data and "allocation" not in data and data["schema"] == 3


def test_an_old_delivery_summary_reads_its_sections_as_deliverys_own_type():
    from mrta_delivery.mission import DeliverySections

    s = read_summary(DATA / "delivery_schema2.json")
    assert isinstance(s.sections, DeliverySections)
    assert s.sections.instance["tasks"][0]["id"] and len(s.sections.instance["cost"]) == 5
    assert s.sections.allocation[0].robot.startswith("robot")
    old = json.loads((DATA / "delivery_schema2.json").read_text())
    new = json.loads(summary_json(s))
    assert new["instance"] == old["instance"] and new["allocation"] == old["allocation"]


def test_a_summary_of_an_unknown_schema_says_which(tmp_path):
    data = json.loads((DATA / "patrol_schema2.json").read_text())
    data["schema"] = 9
    (tmp_path / "s.json").write_text(json.dumps(data))
    with pytest.raises(ConfigError, match="a summary of schema 9; this version reads schemas 2 "
                                          "and 3"):
        read_summary(tmp_path / "s.json")
    (tmp_path / "s.json").write_text('{"who": 1}')  # schema 1's flat patrol dict, or anything
    with pytest.raises(ConfigError, match="not a summary of schema 3: Object missing required"):
        read_summary(tmp_path / "s.json")


def test_a_missions_sections_are_checked_when_the_runner_stores_them():
    assert checked_sections("ping", PingSections, {"pings": [1], "peer": "r"}) == \
        PingSections(pings=[1], peer="r")
    assert checked_sections("patrol", None, None) is None
    with pytest.raises(ConfigError, match=r"returned summary sections \(instance\) but declares "
                                          "no summary_sections type"):
        checked_sections("patrol", None, {"instance": {}})
    with pytest.raises(ConfigError, match="do not match PingSections"):
        checked_sections("ping", PingSections, {"pings": "many", "peer": "r"})

    class Shadow(SummarySections):
        seed: int

    with pytest.raises(ConfigError, match="seed would shadow the framework's fields"):
        check_sections_type("bad", Shadow)
    with pytest.raises(ConfigError, match="must be a subclass of"):
        check_sections_type("bad", msgspec.Struct)


@pytest.mark.parametrize("count, objective, words", [
    (1, None, "1 allocation decision (for its own score, none of the objectives the run is "
              "measured on)"),
    (3, "minsum", "3 allocation decisions (for minsum)")])
def test_the_printed_decisions_say_what_they_were_made_for_in_good_english(count, objective,
                                                                           words):
    """CBBA printed "(no objective)" beside "optimality 0.9589" against MinSum, and one
    decision was "1 allocation decisions" (issue 51, the newcomer's list)."""
    import io

    from rich.console import Console

    from mrta_supervisor.mission.cli import print_summary
    out = io.StringIO()
    s = summary(decisions=summary_module.Decisions(count, 1.5, 2.0, objective))
    print_summary(Console(file=out, width=200), s, "Ping", "CBBA", [])
    assert f"  {words}: computation median 1.5 ms, max 2 ms" in out.getvalue()


def test_the_headline_says_what_was_simulated_and_when_the_work_was_over():
    """The headline called the last completion "N s simulated" while the simulator ran on
    past it (issue 51, the newcomer's list)."""
    import io

    from rich.console import Console

    from mrta_supervisor.mission.cli import print_summary
    out = io.StringIO()
    print_summary(Console(file=out, width=200), summary(ended_at=41.2, recorded_until=42.3,
                                                        duration=60.0), "Ping", "ALLIANCE", [])
    assert ("Ping (ALLIANCE): 42.3 s simulated (every task done by 41.2 s, where the figures "
            "end; --duration 60) at speed max") in out.getvalue()
