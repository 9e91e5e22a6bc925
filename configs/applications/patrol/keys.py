"""The patrol application's keys."""

ALL_REPORTS = "*/patrol/report"
ALL_LOGS = "*/patrol/log"


def report_key(robot_id: str) -> str:
    return f"{robot_id}/patrol/report"


def log_key(robot_id: str) -> str:
    """Where a robot publishes its own PatrolLog (ledger.py)."""
    return f"{robot_id}/patrol/log"
