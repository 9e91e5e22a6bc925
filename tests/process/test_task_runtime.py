"""Tasks at run time (issue 50), across processes: a mission other terminals reach
(`mrta demo --rendezvous`)."""

import json

import pytest

from tests.harness.helpers import free_port

pytestmark = pytest.mark.multiprocess


def test_a_demo_on_a_given_rendezvous_is_reached_from_another_terminal(children, tmp_path):
    """`mrta demo --rendezvous E`: an `mrta echo` started with MRTA_RENDEZVOUS=E alone (no
    other option) hears the run's clock; without --rendezvous the run is private (the same
    echo on the children's rendezvous hears nothing of a run started on its own)."""
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    out = tmp_path / "demo"
    demo = children.mrta("demo", "--application", "delivery", "--architecture", "central",
                         "--speed", "1", "--duration", "20", "--fail", "none", "--no-live",
                         "--no-plots", "--rendezvous", endpoint, "--output", str(out),
                         name="demo")
    demo.wait_line(lambda line: endpoint in line, 60)  # says where the run's bus is
    children.env["MRTA_RENDEZVOUS"] = endpoint
    echo = children.mrta("echo", "robot1/ground_truth", "--count", "1", "--json", name="echo")
    assert echo.wait(120) == 0, echo.stderr[-10:]
    sample = json.loads(echo.stdout[-1])
    assert "pose" in json.dumps(sample), sample
    assert demo.wait(240) == 0, demo.stderr[-20:] + demo.stdout[-20:]
    summary = json.loads((out / "summary.json").read_text())
    # a terminal that only listens is no process of the run, and no disturbance of it
    assert summary["run_status"] == "complete" and summary["lockstep_exact"], summary["run_status"]
