"""MURDOCH's keys: every key an agent publishes on, built in one place. Each message goes out on
the *sender's* key (`robotN/murdoch/<kind>`), so the first chunk names who spoke, as with
ALLIANCE."""

from __future__ import annotations

KINDS = ("announcement", "bid", "award", "claim", "release")
ALL_AGENT_TOKENS = "*/murdoch/agent"


def of(robot_id: str, kind: str) -> str:
    """`robot1/murdoch/claim`; kind is one of KINDS, or `agent` (its liveliness token)."""
    return f"{robot_id}/murdoch/{kind}"


def every(kind: str) -> str:
    """Every robot's `kind` messages: `*/murdoch/claim`."""
    return of("*", kind)


ALL_CLAIMS = every("claim")
