"""`mrta echo` end to end against publishers in other processes, and its input errors."""

import json
import signal
import time

import pytest
from click.testing import CliRunner

from mrta_zenoh.cli.main import cli

KEY = "robot1/alliance/inter_robot_communication"


def run_pair(children, echo_args, items):
    echo = children.mrta("echo", *echo_args, name="echo")
    # the publisher sends once Zenoh reports a matching subscriber: echo's
    pub = children.python("publisher.py", KEY, *items, name="publisher")
    rc = echo.wait(30)
    pub.wait(30)
    return echo, rc


@pytest.mark.multiprocess
def test_echo_prints_typed_samples_from_another_process_and_survives_a_malformed_one(children):
    echo, rc = run_pair(children, ["robot1/**", "--count", "3", "--json"],
                        ["irc:robot1:wander", "garbage", "unknown", "missing", "irc:robot1:report"])
    assert rc == 0, echo.stderr
    lines = [json.loads(x) for x in echo.stdout]
    assert [x["type"] for x in lines] == ["alliance_msgs/InterRobotCommunication",
                                          "vendor_msgs/Battery",
                                          "alliance_msgs/InterRobotCommunication"]
    assert lines[0]["message"]["task_id"] == "wander"
    assert lines[0]["message"]["expected_duration"] == 12.0
    assert lines[1]["message"] == {"level": 3, "items": [1, 2]}
    assert lines[2]["message"]["task_id"] == "report"
    warnings = [x for x in echo.stderr if x.startswith("warning:")]
    assert len(warnings) == 2, echo.stderr
    assert "not msgpack" in warnings[0] and "missing field" in warnings[1]


@pytest.mark.multiprocess
def test_echo_field(children):
    echo, rc = run_pair(children, [KEY, "--field", "/header/frame_id", "--count", "2"],
                        ["irc:robot1:wander", "garbage", "irc:robot1:report"])
    assert rc == 0, echo.stderr
    assert echo.stdout == [f"{KEY}: robot1", f"{KEY}: robot1"]


@pytest.mark.multiprocess
def test_echo_takes_a_ros_topic_name_and_a_dotted_field(children):
    """As a ROS 2 user types them: both were refused (exit 2)."""
    echo, rc = run_pair(children, [f"/{KEY}", "--field", "header.frame_id", "--count", "1"],
                        ["irc:robot1:wander"])
    assert rc == 0, echo.stderr
    assert echo.stdout == [f"{KEY}: robot1"]


@pytest.mark.multiprocess
def test_echo_human_format(children):
    echo, rc = run_pair(children, [KEY, "--count", "1"], ["irc:robot1:wander"])
    assert rc == 0
    assert echo.stdout[0] == f"--- {KEY} [alliance_msgs/InterRobotCommunication]"
    assert "task_id: wander" in echo.stdout


@pytest.mark.multiprocess
def test_echo_exits_promptly_on_sigterm(children, tokens):
    echo = children.mrta("echo", "nothing/**", name="echo")
    tokens.subscribed("nothing/probe", 30, echo)  # running: its subscription is declared
    t0 = time.monotonic()
    echo.signal(signal.SIGTERM)
    assert echo.wait(5) == 0, echo.stderr
    took = time.monotonic() - t0
    assert took < 1.5, f"{took:.2f} s from SIGTERM to exit"


@pytest.mark.parametrize("args,text", [
    (["echo", "a//b"], "empty chunk"),
    (["echo", "k", "--connect", "tcp/127.0.0.1"], "tcp/127.0.0.1"),
    (["echo", "k", "--listen", "localhost:18000"], "localhost:18000"),
    (["echo", "k", "--zenoh-config", "/nonexistent/z.json5"], "/nonexistent/z.json5"),
    (["echo", "k", "--field", "a//b"], "a//b"),
    (["echo", "k", "--namespace", "a b"], "a b"),
])
def test_bad_input_exits_2_with_one_line_naming_the_value(args, text):
    result = CliRunner().invoke(cli, args)
    assert result.exit_code == 2, result.output
    lines = [x for x in result.output.splitlines() if x.strip()]
    assert len(lines) == 1 and text in lines[0], result.output


def test_invalid_zenoh_config_file_exits_2(tmp_path):
    bad = tmp_path / "bad.json5"
    bad.write_text("{ mode: 'peer', listen: { endpoints: [ }")
    result = CliRunner().invoke(cli, ["echo", "k", "--zenoh-config", str(bad)])
    assert result.exit_code == 2 and str(bad) in result.output


@pytest.mark.multiprocess
def test_router_relays_between_a_client_and_a_peer(children):
    router = children.mrta("router", "--listen", children.rendezvous, name="router")
    router.wait_stderr(lambda line: "router listening" in line, 30)  # a router has no token
    # echo as a client of the router; the publisher joins the router (it holds the rendezvous)
    # and sends once Zenoh reports echo's subscription as matching
    echo = children.mrta("echo", KEY, "--mode", "client", "--connect", children.rendezvous,
                         "--count", "1", "--field", "task_id", name="echo")
    pub = children.python("publisher.py", KEY, "irc:robot1:wander", name="publisher")
    assert echo.wait(20) == 0, echo.stderr
    pub.wait(20)
    assert echo.stdout == [f"{KEY}: wander"]
    router.signal(signal.SIGTERM)
    assert router.wait(5) == 0


def test_json_output_is_always_valid_json():
    """A foreign type (decoded generically) may carry NaN; JSON has none: it is written as a
    string, and the line parses."""
    from mrta_zenoh.tools.echo import format_sample
    line = format_sample("robot1/battery", "vendor_msgs/Battery",
                         {"level": float("nan"), "cells": [1.0, float("inf")]}, True, None)
    assert json.loads(line)["message"] == {"level": "nan", "cells": [1.0, "inf"]}


def test_yaml_and_field_output_carry_no_float_noise():
    """What a person reads shows 51.62, not 51.620000000000005 (JSON already did)."""
    from mrta_zenoh.fieldpath import FieldPath
    from mrta_zenoh.tools.echo import format_sample
    body = format_sample("robot1/odom", "T", {"x": 51.620000000000005, "y": [0.1 + 0.2]}, False,
                         None)
    assert "x: 51.62\n" in body and "y: [0.3]" in body
    assert format_sample("robot1/odom", "T", 0.1 + 0.2, False, FieldPath.parse("x")) == \
        "robot1/odom: 0.3"
