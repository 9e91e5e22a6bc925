"""Every architecture's parameter files are typed documents (mrta_zenoh.paramdoc): a bad value
in a shipped file, changed one key at a time, is refused naming the file, the line and the
file's own key path (sized arrays' `task1`, not a list index), with the bound or a "did you
mean"; the shipped files themselves load."""

from pathlib import Path

import pytest
import yaml

from mrta_zenoh.errors import ConfigError
from mrta_agent.cbba.params import load_params as cbba_params
from mrta_agent.central.params import load_dispatcher, load_params as central_params
from mrta_agent.murdoch.params import load_params as murdoch_params
from mrta_agent.ssi.params import load_params as ssi_params

APPS = Path(__file__).resolve().parents[1] / "configs" / "applications"
EV = ("tasks", "task1", "evaluator")

LOADERS = {
    "central": ("delivery_central", lambda r, t: central_params(r, t)),
    "ssi": ("delivery_ssi", lambda r, t: ssi_params("robot1", r, t)),
    "cbba": ("delivery_cbba", lambda r, t: cbba_params("robot1", r, t)),
    "murdoch": ("delivery_murdoch", lambda r, t: murdoch_params(r, t)),
}

# (architecture, robot or tasks file, key path, new value (KeyError: removed), what the error says)
BAD = [
    ("central", "robot", ("lease",), 0.05, "is not longer than a tick"),
    ("central", "robot", ("report_period",), 0, "report_period must be > 0, got 0"),
    ("central", "robot", EV + ("sensors", "sensor0", "topic_name"), "odm",
     "sensor topic 'odm' is not among the robot's sensors (odom) (did you mean 'odom'?)"),
    ("central", "robot", EV + ("plugin_nme",), "x", "(did you mean 'plugin_name'?)"),
    ("central", "robot", ("pose_topic",), "odm", "pose_topic 'odm' is not among"),
    ("central", "tasks", ("tasks", "task2", "id"), "t1", "task id 't1' appears twice"),
    ("ssi", "robot", ("lookahead",), -1, "lookahead must be ≥ 0, got -1"),
    ("ssi", "robot", ("join_wiat",), 1.0, "unknown key 'join_wiat' (did you mean 'join_wait'?)"),
    ("ssi", "robot", ("instance",), KeyError, "missing mandatory key 'instance'"),
    ("ssi", "robot", ("tasks", "task0", "task_id"), "a b", "must be one key chunk"),
    ("cbba", "robot", ("discount",), 1.5, "discount must be in (0, 1], got 1.5"),
    ("cbba", "robot", ("bundle_limit",), 0, "bundle_limit must be a whole number ≥ 1, got 0"),
    ("cbba", "robot", ("bundle_limit",), "two", "bundle_limit must be a whole number ≥ 1, got 'two'"),
    ("cbba", "robot", ("comm_range",), -3, "comm_range must be > 0, got -3"),
    ("murdoch", "robot", ("utility", "skill_wieght"), 1.0, "(did you mean 'skill_weight'?)"),
    ("murdoch", "robot", ("skills", "skill1", "level"), -1,
     "level must be between 0 and 1000000 (0 or more, up to a million), got -1"),
    ("murdoch", "robot", ("lease_timeout",), 0.4, "must be longer than renewal_period"),
    ("murdoch", "robot", ("bid_window",), "soon", "bid_window must be a number, got 'soon'"),
    ("murdoch", "tasks", ("tasks", "task1", "progress_timeout"), float("nan"),
     "progress_timeout must be a finite number"),
]


def _mutate(doc, path, value):
    for key in path[:-1]:
        doc = doc[key]
    if value is KeyError:
        del doc[path[-1]]
    else:
        doc[path[-1]] = value


@pytest.mark.parametrize("arch,which,path,value,text", BAD, ids=[f"{b[0]}-{'/'.join(b[2])}"
                                                                 for b in BAD])
def test_a_bad_value_names_file_line_and_key(tmp_path, arch, which, path, value, text):
    package, load = LOADERS[arch]
    files = {"robot": APPS / package / "config" / f"robot1_{arch}_params.yaml",
             "tasks": APPS / package / "config" / f"tasks_{arch}_params.yaml"}
    doc = yaml.safe_load(files[which].read_text())
    _mutate(doc, path, value)
    files[which] = tmp_path / files[which].name
    files[which].write_text(yaml.safe_dump(doc, sort_keys=False))
    if which == "robot" and "instance" in doc:  # relative to the robot file
        (tmp_path / doc["instance"]).write_text((APPS / package / "config" / doc["instance"])
                                                .read_text())
    with pytest.raises(ConfigError) as info:
        load(files["robot"], files["tasks"])
    msg, key = str(info.value), "/".join(path) if value is not KeyError else path[-1]
    assert f"{files[which]}:" in msg and f"'{key}'" in msg and text in msg, msg


@pytest.mark.parametrize("text,error", [
    ("objective: minsumm\n", "objective 'minsumm' is not one of minsum, makespan, flowtime "
     "(did you mean 'minsum'?)"),
    ("exact_limit: 13\n", "more than 12 tasks"),
    ("solutions: 0\n", "solutions must be a whole number in [1, 10000], got 0"),
    ("spin_rte: 10\n", "unknown key 'spin_rte' (did you mean 'spin_rate'?)"),
    ("time_limit: 1.0e+308\n", "time_limit must be between 0.001 and 86400 s"),
])
def test_the_dispatcher_file_is_a_typed_document(tmp_path, text, error):
    f = tmp_path / "dispatcher.yaml"
    f.write_text("resend_period: 1.0\n" + text)
    with pytest.raises(ConfigError) as info:
        load_dispatcher(f)
    assert f"{f}:2: " in str(info.value) and error in str(info.value), str(info.value)


def test_the_dispatcher_reads_its_defaults_and_an_objective_by_name(tmp_path):
    f = tmp_path / "dispatcher.yaml"
    f.write_text("objective: makespan\n")
    params = load_dispatcher(f)
    assert params.objective.value == "makespan" and params.exact_limit == 8
    assert params.spin_rate == 10.0 and isinstance(params.spin_rate, float)
