"""The layouts for Foxglove / Lichtblick — patrol's and delivery's (the newcomer's list of issue
51: delivery shipped none): every panel's title where both apps read it, legends beside the
data rather than over it, one State Transitions row per robot of the application (every row
visible at 1600×1000), and every topic and field a layout names one the run has."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from mrta_supervisor.live.api import resolve_application
from mrta_supervisor.live.viewer import known_channels

APPS = Path(__file__).resolve().parents[1] / "configs/applications"
LAYOUT = APPS / "patrol/foxglove_layout.json"


@pytest.fixture(scope="module")
def patrol_layout():
    return json.loads(LAYOUT.read_text())


@pytest.fixture(scope="module", params=["patrol", "delivery"])
def app_layout(request):
    return request.param, json.loads((APPS / request.param / "foxglove_layout.json").read_text())


def panels_in(node) -> list[str]:
    if isinstance(node, str):
        return [node]
    return panels_in(node["first"]) + panels_in(node["second"])


def test_every_panel_in_the_tree_is_configured_and_titled(app_layout):
    _, layout = app_layout
    ids = panels_in(layout["layout"])
    assert sorted(ids) == sorted(layout["configById"])
    for pid in ids:  # Lichtblick and Foxglove read a panel's own title from foxglovePanelTitle
        assert layout["configById"][pid].get("foxglovePanelTitle"), pid


def test_plot_legends_stand_beside_the_data(patrol_layout):
    plots = {k: v for k, v in patrol_layout["configById"].items() if k.startswith("Plot!")}
    assert len(plots) == 3
    for pid, cfg in plots.items():
        assert cfg["legendDisplay"] in ("top", "left"), pid  # "floating" covers the lines
        assert len(cfg["paths"]) <= 3 and all(p.get("label") for p in cfg["paths"]), pid


def test_state_transitions_has_one_row_per_robot(app_layout):
    name, layout = app_layout
    app, _ = resolve_application(name)
    paths = layout["configById"]["StateTransitions!alloc"]["paths"]
    assert [p["value"] for p in paths] == [f"/robots/{r.id}/task.activity" for r in app.robots]
    assert [p["label"] for p in paths] == [r.id for r in app.robots]


def test_every_topic_and_field_the_layout_names_is_a_channel_of_the_run(app_layout):
    name, layout = app_layout
    app, _ = resolve_application(name)
    schemas = {topic: (schema, enc) for topic, schema, enc in known_channels(app)}
    named = []
    for cfg in layout["configById"].values():
        for path in cfg.get("paths", ()):
            m = re.fullmatch(r'"?([^"]+?)"?\.(\w+)', path["value"])
            named.append((m.group(1), m.group(2)))
        for key in ("topicPath", "topicToRender"):
            if key in cfg:
                named.append((cfg[key], None))
        named += [(t, None) for t in cfg.get("topics", {})]
    assert len(named) >= (15 if name == "patrol" else 8)
    for topic, field in named:
        assert topic in schemas, topic
        (_, encoding, data), _ = schemas[topic]
        if field is not None:
            assert encoding == "jsonschema" and field in json.loads(data)["properties"], \
                (topic, field)
