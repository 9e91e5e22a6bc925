"""Teams of many robots (issue 39 point 5): what a robot's start-up costs per task, and a
generated N-robot delivery run in lockstep to its end."""

from __future__ import annotations

import importlib.metadata

from mrta_agent.runtime import plugins


def test_a_robot_reads_the_installed_entry_points_once_whatever_its_tasks(monkeypatch):
    """A delivery robot loads one evaluator per task: reading every distribution's entry points
    for each (≈ 0.1 s) made start-up grow with the tasks; they are read once per import path."""
    calls = []

    def counting():
        calls.append(1)
        return importlib.metadata.entry_points()

    monkeypatch.setattr(plugins, "entry_points", counting)
    plugins._entry_points.cache_clear()
    plugins._group.cache_clear()
    try:
        loaded = {plugins.load_plugin("evaluator", "delivery/task_open") for _ in range(50)}
        assert len(loaded) == 1 and len(calls) == 1
        monkeypatch.syspath_prepend("/nonexistent-for-this-test")  # another import path
        plugins.load_plugin("evaluator", "delivery/task_open")
        assert len(calls) == 2
    finally:
        plugins._entry_points.cache_clear()
        plugins._group.cache_clear()
