"""Other terminals watching a run that takes tasks at run time (issue 50, docs/tasks.md): on a
reachable mission (`mrta demo --rendezvous`), `mrta echo tasks/change` prints what entered the
run as it enters, and a live view started after the submissions — `mrta supervise` and
`mrta view` — still knows them: it asks the intake for the run's task set so far
(`tasks/history`, a queryable: the late joiner's history, as rmw_zenoh's transient local) as
it starts, and hears the rest live — on a secured fleet too, under the observer's certificate."""

import json

import pytest
from click.testing import CliRunner
from mcap.reader import make_reader

from mrta_zenoh.cli.main import cli
from tests.harness.helpers import free_port

pytestmark = [pytest.mark.multiprocess, pytest.mark.slow]


def cancelled(snapshot: dict) -> bool:
    return any(t["id"] == "t3" and t["state"] == "cancelled" for t in snapshot["tasks"])


@pytest.mark.timeout(420)
def test_echo_hears_the_changes_and_a_view_started_late_knows_the_earlier_ones(children,
                                                                              tmp_path):
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    run = children.mrta("demo", "--application", "delivery", "--architecture", "central",
                        "--duration", "40", "--fail", "none", "--no-live", "--no-plots",
                        "--speed", "1", "--rendezvous", endpoint, "--output",
                        str(tmp_path / "run"), name="demo")
    run.wait_line(lambda line: endpoint in line, 60)
    children.env["MRTA_RENDEZVOUS"] = endpoint  # the other terminals: that variable alone
    echo = children.mrta("echo", "tasks/change", "--json", "-n", "2", name="echo")
    listing = children.mrta("task", "list", "--json", "--timeout", "120", name="list")
    assert listing.wait(150) == 0, listing.stderr[-3:]  # the intake answers: the run is up
    submit = children.mrta("task", "submit", "n1", "--set", "position=[2.0,1.5]",
                           "--priority", "2", name="submit")
    assert submit.wait(120) == 0 and " accepted at " in submit.stdout[-1], submit.stderr[-3:]
    cancel = children.mrta("task", "cancel", "t3", name="cancel")
    assert cancel.wait(120) == 0 and " accepted at " in cancel.stdout[-1], cancel.stderr[-3:]
    assert echo.wait(60) == 0, echo.stderr[-3:]
    heard = [json.loads(line)["message"] for line in echo.stdout if line.startswith("{")]
    assert [(h["op"], h["task_id"]) for h in heard] == [("submit", "n1"), ("cancel", "t3")]

    # started after both changes: it learns them from the intake's history
    late = children.mrta("supervise", "delivery_central", "--json", "--sim-time", "--rate", "1",
                         name="supervise")
    late.wait_line(lambda line: line.startswith("{") and '"n1"' in line, 60)
    late.wait_line(lambda line: line.startswith("{") and cancelled(json.loads(line)), 60)
    late.stop()
    view = children.mrta("view", "delivery_central", "--no-server", "-o", tmp_path / "v.mcap",
                         "--sim-time", "--duration", "6", name="view")
    assert view.wait(90) == 0, view.stderr[-5:]
    with open(tmp_path / "v.mcap", "rb") as f:
        states = [json.loads(m.data) for _, c, m in make_reader(f).iter_messages(
            topics=["/supervisor/state"])]
    assert states and all("n1" in {t["id"] for t in s["tasks"]} for s in states), \
        (len(states), view.stderr[-5:])
    assert run.wait(300) == 0, run.stderr[-20:]


@pytest.mark.timeout(420)
def test_a_view_started_late_on_a_secured_fleet_learns_the_earlier_ones(children, tmp_path):
    """The same on a secured fleet (`mrta secure init --submitter ops --observer supervisor`,
    `mrta demo --secure`): the submitter's certificate submits and cancels through the router,
    and a supervisor started afterwards under the observer's certificate still learns both —
    its query of `tasks/history` and the intake's reply pass the fleet's access control."""
    folder = tmp_path / "fleet"
    result = CliRunner().invoke(cli, ["secure", "init", str(folder), *sum(
        (["--robot", f"robot{i}"] for i in range(1, 6)), []), "--observer", "supervisor",
        "--observer", "recorder", "--submitter", "ops",
        "--endpoint", f"tls/127.0.0.1:{free_port()}"])
    assert result.exit_code == 0, result.output
    run = children.mrta("demo", "--application", "delivery", "--architecture", "ssi",
                        "--secure", folder, "--duration", "40", "--speed", "1", "--no-live",
                        "--no-plots", "--output", tmp_path / "run", name="demo")
    run.wait_stderr(lambda s: "processes meet at tls/" in s, 120)  # the router is up
    ops = ("--as", "ops", "--zenoh-config", folder / "ops.json5", "--timeout", "120")
    submit = children.mrta("task", "submit", "n1", "--set", "position=[2.0,1.5]", *ops,
                           name="submit")
    assert submit.wait(180) == 0 and " accepted at " in submit.stdout[-1], submit.stderr[-3:]
    cancel = children.mrta("task", "cancel", "t3", *ops, name="cancel")
    assert cancel.wait(120) == 0 and " accepted at " in cancel.stdout[-1], cancel.stderr[-3:]

    late = children.mrta("supervise", "delivery_ssi", "--json", "--sim-time", "--rate", "1",
                         "--zenoh-config", folder / "supervisor.json5", name="supervise")
    late.wait_line(lambda line: line.startswith("{") and '"n1"' in line, 90)
    late.wait_line(lambda line: line.startswith("{") and cancelled(json.loads(line)), 60)
    late.stop()
    assert run.wait(300) == 0, run.stderr[-20:]
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["run_status"] == "complete" and summary["lockstep_exact"], \
        summary["disturbances"]
