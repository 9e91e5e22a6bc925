"""One message for a robot's progress on its route (`route_msgs/Progress`,
robot_agent/route/messages.py) under every route-serving architecture: central's robots send
it too, with the queue version they applied, which its dispatcher reads off the bus."""

from __future__ import annotations

from mrta_agent.cbba.architecture import CBBA
from mrta_agent.central.architecture import CENTRAL
from mrta_agent.route.messages import Progress, Queued
from mrta_agent.ssi.architecture import SSI
from tests.harness.central_team import Team
from tests.test_central_dispatcher import SQUARE


def test_central_ssi_and_cbba_share_the_progress_and_queued_messages():
    for arch in (CENTRAL, SSI, CBBA):
        assert arch.messages["progress"] is Progress and arch.messages["queued"] is Queued
    assert Progress.TYPE_NAME == "route_msgs/Progress"


def test_central_robots_report_the_queue_version_they_applied():
    team = Team(SQUARE)
    heard: list[Progress] = []
    sub = team.buses["robot1"].subscribe("*/central/progress", lambda s: heard.append(s.message),
                                         msg_type=Progress)
    try:
        team.step(30)
    finally:
        sub.close()
    sent = team.dispatcher.sent
    latest = {}
    for m in heard:
        latest[m.header.frame_id] = m
    assert set(latest) == {"robot1", "robot2"}
    for robot, m in latest.items():
        assert m.version == sent[robot].version > 0  # the dispatcher's queue, applied
        assert not m.holding
