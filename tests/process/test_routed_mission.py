"""A mission through the run's own router (supervisor/mission/runner.py, ROUTER_FROM): from that many
robots the run's processes are the router's clients instead of a peer mesh, whose N² links cost
every process CPU in proportion to N (benchmarks/README.md, team sizes)."""

from __future__ import annotations

import json
import time
from pathlib import Path

import pytest

from tests.test_mission_hygiene import children_of

SAME = ("who_did_what", "decisions", "first_full_allocation", "metrics", "ended_at", "coverage",
        "overlaps", "robots", "recorded_until")


@pytest.mark.multiprocess
@pytest.mark.slow
@pytest.mark.timeout(900)
def test_a_routed_mission_does_what_the_peer_mesh_does(children, tmp_path):
    """In lockstep the topology must not change the run: the same seed, with a crash, gives
    the same who-did-what, decisions, first allocation and metrics through a router (here
    from the first robot on, tests/procs/routed_demo.py) as on the peer mesh."""
    args = ("-q", "demo", "--application", "delivery", "--duration", "30", "--speed", "0",
            "--no-live", "--no-plots", "--fail", "robot1@6", "--seed", "3")
    peer = children.mrta(*args, "--output", str(tmp_path / "peer"), name="peer")
    assert peer.wait(400) == 0, peer.tail(30)
    routed = children.python("routed_demo.py", *args, "--output", str(tmp_path / "routed"),
                             name="routed")
    seen: set[tuple[str, ...]] = set()  # the run's processes, by command line
    deadline = time.monotonic() + 400
    while routed.running() and time.monotonic() < deadline:
        for pid in children_of(routed.pid):
            try:
                seen.add(tuple(Path(f"/proc/{pid}/cmdline").read_bytes().decode().split("\0")))
            except OSError:
                pass  # ended meanwhile
        time.sleep(0.2)
    assert routed.wait(60) == 0, routed.tail(30)
    assert any("router" in argv for argv in seen), "no router among the run's processes"
    others = [argv for argv in seen if "router" not in argv]
    assert len(others) >= 7  # the simulator, 5 agents, the recorder
    assert all("client" in argv for argv in others), "a process of the run is no client"
    a, b = (json.loads((tmp_path / run / "summary.json").read_text())
            for run in ("peer", "routed"))
    assert a["lockstep_exact"] is True and b["lockstep_exact"] is True
    assert a["run_status"] == b["run_status"] == "complete"
    assert a["failure"] == b["failure"] and a["failure"] is not None
    for field in SAME:
        assert a[field] == b[field], field
