"""A third party's application, pip-installed: examples/ping_app (own pyproject.toml; one message
type, one layer, one evaluator, an rqt_mrta application), found through entry points only.

It is installed with `pip install --target` into a folder of its own that the children get on
PYTHONPATH, so the test venv itself is left as it was.
"""

import os
import subprocess
import sys

import msgpack
import pytest

from tests.harness.helpers import ROOT

pytestmark = pytest.mark.multiprocess


@pytest.fixture(scope="module")
def ping_site(tmp_path_factory):
    site = tmp_path_factory.mktemp("site")
    subprocess.run([sys.executable, "-m", "pip", "install", "-q", "--no-deps",
                    "--target", str(site), str(ROOT / "examples" / "ping_app")],
                   check=True, capture_output=True, text=True, timeout=90)  # + the test's own waits < 180 s
    assert (site / "ping_app" / "package.xml").is_file()
    return site


@pytest.fixture
def ping_children(children, ping_site):
    children.env["PYTHONPATH"] = os.pathsep.join(
        [str(ping_site), children.env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    return children


@pytest.mark.slow
def test_its_application_is_listed_and_valid(ping_children):
    apps = ping_children.mrta("app", "list", "--json", name="app list")
    assert apps.wait(60) == 0, apps.stderr
    found = [line for line in apps.stdout if '"ping"' in line]
    assert found and '"alliance"' in found[0] and "robot2" in found[0]


@pytest.mark.slow
def test_an_agent_runs_its_layer_and_echo_decodes_its_message_by_type(ping_children):
    site = ping_children.env["PYTHONPATH"].split(os.pathsep)[0]
    config = os.path.join(site, "ping_app", "config")
    echo = ping_children.mrta("echo", "robot1/ping", "--json", "--count", "3", name="echo")
    agent = ping_children.mrta(
        "agent", "robot1", "--robot-params", os.path.join(config, "robot1_alliance_params.yaml"),
        "--tasks-params", os.path.join(config, "tasks_alliance_params.yaml"),
        "--layers-params", os.path.join(config, "layers_alliance_params.yaml"), name="agent")
    agent.wait_stderr(lambda line: "activated announce" in line, 60)
    # a sample missing a field: a typed decoder rejects it, a generic one would print it
    missing_count = msgpack.packb({"header": {"frame_id": "robot1", "stamp": 1.0, "seq": 1}})
    bad = ping_children.python("publisher.py", "robot1/ping",
                               f"hex:ping_msgs/Ping:{missing_count.hex()}", name="bad publisher")
    first = echo.wait_json(lambda o: o.get("type") == "ping_msgs/Ping", 60)
    assert first["key"] == "robot1/ping" and first["message"]["count"] >= 1
    assert echo.wait(60) == 0
    bad.wait_json(lambda o: "done" in o, 30)
    assert any("missing" in line and "count" in line for line in echo.stderr), echo.stderr
