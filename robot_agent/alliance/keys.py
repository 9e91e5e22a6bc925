"""ALLIANCE's keys (docs/architecture.md): every key an agent publishes on, built in one place."""

from __future__ import annotations

from mrta_zenoh.keys import task_chunk

ALL_INTER_ROBOT_COMMUNICATION = "*/alliance/inter_robot_communication"
ALL_MOTIVATION = "*/alliance/motivation/*"
ALL_AGENT_TOKENS = "*/alliance/agent"


def inter_robot_communication(robot_id: str) -> str:
    return f"{robot_id}/alliance/inter_robot_communication"


def motivation(robot_id: str, task_id: str) -> str:
    return f"{robot_id}/alliance/motivation/{task_chunk(task_id)}"


def sensory_feedback(robot_id: str) -> str:
    return f"{robot_id}/alliance/sensory_feedback"


def agent_token(robot_id: str) -> str:
    """Declared once the agent is ready: alive means ready."""
    return f"{robot_id}/alliance/agent"
