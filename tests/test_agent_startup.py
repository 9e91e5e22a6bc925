"""What an agent loads to start: a registered plugin name reads no package's alias table (a
delivery robot loaded patrol's layers and ledger to read theirs, once per task)."""

from __future__ import annotations

import pytest

from mrta_agent.runtime import plugins


def test_a_registered_plugin_name_reads_no_alias_table(monkeypatch):
    calls = []

    def counting():
        calls.append(1)
        return {}

    monkeypatch.setattr(plugins, "aliases", counting)
    cls = plugins.load_plugin("evaluator", "delivery/task_open")
    assert cls.__name__ == "TaskOpen" and calls == []


def test_an_old_name_still_finds_its_plugin_through_the_aliases():
    """The reference YAML's names (`alliance_test/*`) are aliases: looked up when no plugin is
    registered under the name."""
    table = plugins.aliases()
    old, new = next((o, n) for o, n in sorted(table.items())
                    if n in plugins.plugin_entry_points(plugins.GROUPS["layer"]))
    assert old not in plugins.plugin_entry_points(plugins.GROUPS["layer"])
    assert plugins.load_plugin("layer", old) is plugins.load_plugin("layer", new)
    with pytest.raises(Exception, match="unknown layer plugin"):
        plugins.load_plugin("layer", "no_such/layer")
