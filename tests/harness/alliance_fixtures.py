"""Small ALLIANCE parameter sets for tests, written in the dissertation's YAML layout."""

from pathlib import Path

import yaml

from mrta_agent.alliance.params import BehaviourSetParams, RobotParams


def bset(task, theta=100.0, fast=10.0, expected=50.0, yielding=30.0, giving_up=60.0):
    return BehaviourSetParams(task, expected, theta, yielding, giving_up, fast,
                              "alliance_test/updated_sensory", ("sonar",))


def robot(*sets, spin=1.0, tau=5.0, broadcast=1.0):
    return RobotParams("R", spin, broadcast, tau, 10.0, (), tuple(sets))


def robot_yaml(sets, spin=10.0, broadcast=5.0, tau=1.0, sensors=("odom", "sonar")):
    """sets: list of dicts with task, theta, fast, expected, yielding, giving_up."""
    plugins = {"odom": "alliance_test/odometry", "sonar": "alliance_test/point_cloud"}
    doc = {"name": "test robot", "spin_rate": spin, "broadcast_rate": broadcast,
           "timeout_duration": tau, "buffer_horizon": 5.0,
           "sensors": {"size": len(sensors)}, "behaviour_sets": {"size": len(sets)}}
    for i, t in enumerate(sensors):
        doc["sensors"][f"sensor{i}"] = {"plugin_name": plugins[t], "topic_name": t,
                                        "timeout_duration": 1.0, "buffer_horizon": 1.0}
    for i, s in enumerate(sets):
        doc["behaviour_sets"][f"behaviour_set{i}"] = {
            "task_id": s["task"], "task_expected_duration": s.get("expected", 1000.0),
            "motivational_behaviour": {
                "threshold": s.get("theta", 100.0),
                "acquiescence": {"yielding_delay": s.get("yielding", 1000.0),
                                 "giving_up_delay": s.get("giving_up", 2000.0)},
                "impatience": {"fast_rate": s["fast"]},
                "sensory_feedback": {"plugin_name": "alliance_test/updated_sensory",
                                     "sensors": {"size": 1, "sensor0": {"topic_name": "sonar"}}}}}
    return doc


def tasks_yaml(task_ids, layers=None):
    doc = {"tasks": {"size": len(task_ids)}}
    for i, t in enumerate(task_ids):
        ls = (layers or {}).get(t, [])
        entry = {"id": t, "name": t.title(), "layers": {"size": len(ls)}}
        for j, name in enumerate(ls):
            entry["layers"][f"layer{j}"] = {"plugin_name": name}
        doc["tasks"][f"task{i}"] = entry
    return doc


def write(path: Path, doc) -> Path:
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path
