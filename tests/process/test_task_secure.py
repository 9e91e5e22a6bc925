"""The entry point's reliability across processes (issue 50.6): on a secured fleet only a
submitter's certificate may send task requests, on its own key — a robot's certificate cannot
submit (refused at start by the identity check, and a request it publishes anyway is dropped by
the router's access control: the intake never hears it); a flood beyond a submitter's bound is
refused with its reason, counted, and does not hold another submitter back."""

import sys

import pytest
from click.testing import CliRunner

from mrta_zenoh.cli.main import cli
from tests.harness.helpers import CONFIGS, Child, free_port
from tests.test_secure import wait_accepting

pytestmark = pytest.mark.multiprocess

INSTANCE = CONFIGS / "applications" / "delivery" / "config" / "instance.yaml"

FORGER = """
import sys, time
from mrta_zenoh.bus import BusOptions, open_bus
from mrta_zenoh.messages import Header
from mrta_zenoh.tasks.messages import Request, request_key
with open_bus(BusOptions(zenoh_config=sys.argv[1])) as bus:
    for who in ("robot1", "ops"):   # its own name, and the submitter's
        for i in range(20):
            bus.publish(request_key(who), Request(Header(who, 0.0, i), f"f{i}", "submit",
                                                  f"forged-{who}-{i}", '{"position": [1, 2]}'))
            time.sleep(0.02)
print("sent", flush=True)
"""


@pytest.mark.timeout(300)
def test_only_a_submitters_certificate_submits(children, tmp_path):
    folder = tmp_path / "fleet"
    endpoint = f"tls/127.0.0.1:{free_port()}"
    result = CliRunner().invoke(cli, ["secure", "init", str(folder), "--robot", "robot1",
                                      "--submitter", "ops", "--no-simulator",
                                      "--endpoint", endpoint])
    assert result.exit_code == 0, result.output
    assert (folder / "ops.json5").is_file() and (folder / "tasks.json5").is_file()
    router = children.mrta("router", "--zenoh-config", folder / "router.json5", name="router")
    router.wait_stderr(lambda line: "router listening on tls/" in line, 30)
    wait_accepting(endpoint)
    children.mrta("task", "serve", "--instance", INSTANCE, "--zenoh-config",
                  folder / "tasks.json5", name="intake")

    def task(*args, as_="ops", config="ops"):
        return children.mrta("task", *args, "--as", as_, "--zenoh-config",
                             folder / f"{config}.json5", "--timeout", "60", name=f"task {as_}")

    ok = task("submit", "n1", "--set", "position=[1.0,2.0]")
    assert ok.wait(90) == 0 and ok.stdout[-1].startswith("n1 accepted at "), ok.stderr[-5:]
    robot = task("submit", "n2", "--set", "position=[1.0,2.0]", as_="robot1", config="robot1")
    assert robot.wait(90) == 2 and "certificate" in robot.stderr[-1], robot.stderr[-3:]
    forger = Child([sys.executable, "-c", FORGER, str(folder / "robot1.json5")], children.env,
                   "forger")
    children.all.append(forger)
    assert forger.wait(60) == 0, forger.stderr[-5:]
    listing = task("list", "--json")
    assert listing.wait(90) == 0, listing.stderr[-5:]
    assert '"n1"' in listing.stdout[-1] and "forged" not in listing.stdout[-1]


@pytest.mark.timeout(300)
def test_a_flood_is_refused_counted_and_does_not_hold_others_back(children, tmp_path):
    children.mrta("task", "serve", "--instance", INSTANCE, "--burst", "50", "--rate", "5",
                  name="intake")
    lines = ["tasks:"] + [f"  f{i}: {{position: [1.0, 0.5]}}" for i in range(300)]
    (tmp_path / "flood.yaml").write_text("\n".join(lines) + "\n")
    flood = children.mrta("task", "submit", "--file", tmp_path / "flood.yaml", "--as", "flood",
                          "--timeout", "60", name="flood")
    assert flood.wait(90) == 2, flood.stderr[-3:]
    accepted = [line for line in flood.stdout if " accepted at " in line]
    refused = [line for line in flood.stdout if " refused: rate: " in line]
    assert len(accepted) + len(refused) == 300 and 50 <= len(accepted) < 80, flood.stdout[-3:]
    assert "not accepted" in flood.stderr[-1]
    calm = children.mrta("task", "submit", "c1", "--set", "position=[2.0,1.5]", "--as", "calm",
                         name="calm")
    assert calm.wait(90) == 0 and calm.stdout[-1].startswith("c1 accepted at ")
