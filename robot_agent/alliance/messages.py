"""alliance_msgs: what ALLIANCE agents tell each other and the supervisor (field names as in the
original alliance_msgs, so field paths written for rqt_mrta — `header/frame_id` — still work)."""

from __future__ import annotations

from mrta_zenoh.messages import Finite, Header, Message, message


@message("alliance_msgs/InterRobotCommunication")
class InterRobotCommunication(Message):
    """"I am doing `task_id`": broadcast while a behaviour set is active (Parker's E.3).

    `active_since` (our addition; optional on the wire, -1 = not reported): when the sender's
    current activation began, on its clock — what lets two robots on one task agree on which
    one yields (high_level.py)."""

    header: Header
    task_id: str
    expected_duration: Finite
    active_since: Finite = -1.0


@message("alliance_msgs/Motivation")
class Motivation(Message):
    """One behaviour set's state after a tick: rqt_alliance's seven panels."""

    header: Header
    task_id: str
    impatience: Finite
    acquiescent: bool
    suppressed: bool
    resetted: bool
    applicable: bool
    motivation: Finite
    threshold: Finite
    active: bool


@message("alliance_msgs/SensoryFeedback")
class SensoryFeedback(Message):
    header: Header
    task_id: str
    applicable: bool
