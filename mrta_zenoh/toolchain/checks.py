"""What `mrta app validate` checks beyond the rqt_mrta.xml file: each robot's parameter files,
read by the application's architecture exactly as its agent reads them at start
(`Architecture.check_files`), so an application that validates is one its agents accept."""

from __future__ import annotations

from pathlib import Path

from ..architectures import architecture
from ..errors import ConfigError
from ..keys import normalize_robot_id
from .model import Application


def check_robot_files(package: Path, app: Application) -> list[str]:
    """The robots whose files were checked (those whose parameter file the package holds,
    under the names `mrta app new` writes); the first bad file raises its ConfigError."""
    try:
        arch = architecture(app.architecture)
    except ConfigError as exc:  # an rqt_mrta package whose contract nobody registered
        raise ConfigError(exc.detail, file=app.source, line=app.architecture_line,
                          element="<architecture>") from None
    config = package / "config"
    stem = arch.param_stem
    tasks, layers = config / f"tasks_{stem}_params.yaml", config / f"layers_{stem}_params.yaml"
    checked = []
    for robot in app.robots:
        rid = normalize_robot_id(robot.id)
        params = config / f"{rid}_{stem}_params.yaml"
        if not (params.is_file() and tasks.is_file()):
            continue
        arch.check_files(rid, params, tasks, layers if layers.is_file() else None)
        checked.append(rid)
    return checked
