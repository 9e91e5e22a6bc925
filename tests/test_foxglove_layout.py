"""The patrol layout for Foxglove / Lichtblick: every panel's title where both apps
read it, legends beside the data rather than over it, one State Transitions row per robot (every
row visible at 1600×1000), and every topic and field it names one the run has."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from mrta_supervisor.live.api import resolve_application
from mrta_supervisor.live.viewer import known_channels

LAYOUT = Path(__file__).resolve().parents[1] / "configs/applications/patrol/foxglove_layout.json"


@pytest.fixture(scope="module")
def layout():
    return json.loads(LAYOUT.read_text())


def panels_in(node) -> list[str]:
    if isinstance(node, str):
        return [node]
    return panels_in(node["first"]) + panels_in(node["second"])


def test_every_panel_in_the_tree_is_configured_and_titled(layout):
    ids = panels_in(layout["layout"])
    assert sorted(ids) == sorted(layout["configById"])
    for pid in ids:  # Lichtblick and Foxglove read a panel's own title from foxglovePanelTitle
        assert layout["configById"][pid].get("foxglovePanelTitle"), pid


def test_plot_legends_stand_beside_the_data(layout):
    plots = {k: v for k, v in layout["configById"].items() if k.startswith("Plot!")}
    assert len(plots) == 3
    for pid, cfg in plots.items():
        assert cfg["legendDisplay"] in ("top", "left"), pid  # "floating" covers the lines
        assert len(cfg["paths"]) <= 3 and all(p.get("label") for p in cfg["paths"]), pid


def test_state_transitions_has_one_row_per_robot(layout):
    paths = layout["configById"]["StateTransitions!alloc"]["paths"]
    assert [p["value"] for p in paths] == [f"/robots/robot{i}/task.activity" for i in (1, 2, 3)]


def test_every_topic_and_field_the_layout_names_is_a_channel_of_the_run(layout):
    app, _ = resolve_application("patrol")
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
    assert len(named) >= 15
    for topic, field in named:
        assert topic in schemas, topic
        (_, encoding, data), _ = schemas[topic]
        if field is not None:
            assert encoding == "jsonschema" and field in json.loads(data)["properties"], \
                (topic, field)
