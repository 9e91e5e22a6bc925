"""What `mrta app validate` checks beyond the rqt_mrta.xml file: each robot's parameter files,
read by the application's architecture exactly as its agent reads them at start
(`Architecture.check_files`), so an application that validates is one its agents accept.

`mrta app new` runs the same check on the files it is about to write (`check_package_files`),
before writing any, and asks the architecture which sections of the layers file the robots'
plugins read (`read_layer_sections`), so that it asks for and writes only those.
"""

from __future__ import annotations

import contextlib
import re
import tempfile
from pathlib import Path
from typing import Iterator

from ..architectures import Architecture as Contract
from ..architectures import architecture, architecture_names
from ..errors import ConfigError
from ..yamlfile import YamlDoc, load_yaml
from .model import ApplicationFile


class PackageRefused(ConfigError):
    """A file `mrta app new` generated is one its architecture refuses; `generated` is its path
    in the package (config/robot1_alliance_params.yaml), so the wizard can ask again for the
    answers that made it."""

    def __init__(self, message: str, generated: str, *, file: str | None = None,
                 line: int | None = None):
        super().__init__(message, file=file, line=line)
        self.generated = generated


def contract_of(app: ApplicationFile) -> Contract:
    try:
        return architecture(app.architecture)
    except ConfigError as exc:  # an rqt_mrta package whose contract nobody registered
        raise ConfigError(exc.detail, file=app.source, line=app.architecture_line,
                          element="<architecture>") from None


def check_robot_files(package: Path, app: ApplicationFile) -> list[str]:
    """The robots whose files were checked (those whose parameter file the package holds,
    under the names `mrta app new` writes); the first bad file raises its ConfigError."""
    arch = contract_of(app)
    config = package / "config"
    stem = arch.param_stem
    tasks, layers = config / f"tasks_{stem}_params.yaml", config / f"layers_{stem}_params.yaml"
    checked = []
    for robot in app.robots:
        rid = robot.id
        params = config / f"{rid}_{stem}_params.yaml"
        if not (params.is_file() and tasks.is_file()):
            continue
        arch.check_files(rid, params, tasks, layers if layers.is_file() else None)
        checked.append(rid)
    return checked


def checkable(app: ApplicationFile) -> bool:
    """Whether the application's architecture has a registered contract to check files with
    (an rqt_mrta package alone describes an architecture but runs nothing)."""
    return app.architecture in architecture_names()


@contextlib.contextmanager
def scratch_package(files: dict[str, bytes]) -> Iterator[Path]:
    """`files` (relative path → bytes) written into a temporary folder, removed afterwards."""
    with tempfile.TemporaryDirectory(prefix="mrta-app-new-") as tmp:
        root = Path(tmp)
        for rel, data in files.items():
            (root / rel).parent.mkdir(parents=True, exist_ok=True)
            (root / rel).write_bytes(data)
        yield root


def layers_config_id(app: ApplicationFile) -> str | None:
    """The id of the layers file's config template (`layers_<stem>_params`), None when the
    architecture has no contract."""
    return f"layers_{architecture(app.architecture).param_stem}_params" if checkable(app) \
        else None


def read_layer_sections(files: dict[str, bytes], app: ApplicationFile) -> frozenset[str] | None:
    """The sections of the layers file that some robot's plugins read, from the package's
    robot and tasks files; None when the architecture cannot say."""
    if not checkable(app):
        return None
    arch = contract_of(app)
    stem = arch.param_stem
    read: set[str] = set()
    with scratch_package(files) as root:
        config = root / "config"
        for robot in app.robots:
            rid = robot.id
            try:
                sections = arch.layer_sections(rid, config / f"{rid}_{stem}_params.yaml",
                                               config / f"tasks_{stem}_params.yaml")
            except ConfigError:
                return None  # the files are refused: check_package_files says where
            if sections is None:
                return None
            read |= sections
    return frozenset(read)


def check_package_files(files: dict[str, bytes], app: ApplicationFile,
                        answers: YamlDoc | None = None) -> bool:
    """The files `mrta app new` is about to write, checked as `mrta app validate` checks a
    package (check_robot_files) before any is written; False when the architecture has no
    contract to check them with. A refusal is a PackageRefused naming the generated file and
    line, located in the answers file when there is one, and — for a robot's task that the
    tasks file lacks — the tasks the robots were given: they are the application's (the wizard
    asks for them first), so the fix is in the tasks file even where the architecture's "did
    you mean" points at its misspelling."""
    if not checkable(app):
        return False
    with scratch_package(files) as root:
        try:
            check_robot_files(root, app)
        except ConfigError as exc:
            file, line = exc.file, exc.line
            m = re.fullmatch(r"(.*):(\d+)", file or "")
            if m and line is None:  # plugins name their place as one "file:line" string
                file, line = m.group(1), int(m.group(2))
            rel = Path(file).relative_to(root).as_posix() if file else ""
            what = f"{exc.element}: {exc.detail}" if exc.element else exc.detail
            where = f"{rel}:{line}" if line else rel
            note = at = None
            generated = rel
            if exc.element == "'task_id'":  # a robot's task the tasks file lacks
                note = (f"; the robots were given {', '.join(app.tasks())}, and the tasks file "
                        "must define each of them")
                # the answers to ask again are the tasks file's: asked for robot1's file, the
                # wizard re-asked its ~25 questions forever (issue 51, the newcomer's list)
                generated = f"config/tasks_{contract_of(app).param_stem}_params.yaml"
                if answers is not None:  # what to fix is the tasks file's answers
                    at = answers.line(("configs", f"tasks_{contract_of(app).param_stem}_params"))
            message = f"the package would not load: {where}: {what}{note or ''}"
            if answers is not None and file and line:
                at = _answers_line(answers, load_yaml(file), line, rel)
            raise PackageRefused(message, generated,
                                 file=str(answers.path) if answers else None, line=at) from None
    return True


def _answers_line(answers: YamlDoc, generated: YamlDoc, line: int, rel: str) -> int | None:
    """The answers file's line for a generated file's line: the generated key at that line,
    its path taken back to the answers' form (`sensors/sensor0/x` → `sensors`, 0, `x`) under
    `configs/<config id>[/<robot>]`."""
    path = max((p for p, n in generated.lines.items() if n == line), key=len, default=None)
    if path is None:
        return None
    stem = Path(rel).stem
    config = (stem,)
    for rid in answers.data.get("robots") or {}:
        if isinstance(rid, str) and stem.startswith(f"{rid}_"):
            config = (stem[len(rid) + 1:], rid)
    out: list = ["configs", *config]
    for part in path:
        m = re.fullmatch(r"([a-z_]+?)(\d+)", str(part))
        if m and out and str(out[-1]).startswith(m.group(1)):
            out.append(int(m.group(2)))  # `sensors`/`sensor0` → `sensors`, 0
        elif part != "size":
            out.append(part)
    return answers.line(tuple(out))
