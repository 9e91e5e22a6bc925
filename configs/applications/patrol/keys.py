"""The patrol application's keys."""

ALL_REPORTS = "*/patrol/report"


def report_key(robot_id: str) -> str:
    return f"{robot_id}/patrol/report"
