"""Writing output whole or not at all: one file (a plot, a summary) or a folder of files (a
generated package, a fleet's certificates).

Everything is built beside its destination under a temporary name, then renamed into place in
one step: whoever reads the destination — another process, or the user after a crash, Ctrl-C or
a full disk — finds the old content or the new, never half of either. Every writer of the
project goes through `write_atomically`, so that guarantee (and the clean-up of the temporary
on failure) is written once.
"""

from __future__ import annotations

import os
import shutil
import tempfile
import uuid
from collections.abc import Callable, Mapping
from pathlib import Path

from .errors import ConfigError


def write_atomically(target: Path | str, write: Callable[[Path], None], *,
                     folder: bool = False) -> Path:
    """Call `write(tmp)` to build the content at a temporary path beside `target`, then rename
    it to `target`, replacing what was there; returns `target`.

    `folder`: `tmp` is an empty directory to fill (its parents are created), otherwise a file
    name for `write` to create. On any failure the temporary is removed and `target` is left as
    it was; an OSError becomes a ConfigError naming `target` (the user chose where to write).
    """
    target = Path(target)
    try:
        if folder:
            target.parent.mkdir(parents=True, exist_ok=True)
            tmp = Path(tempfile.mkdtemp(prefix=f".{target.name}.", dir=target.parent))
        else:
            # not created here: `write` creates it, with the permissions any new file gets
            tmp = target.with_name(f".{target.name}.{uuid.uuid4().hex[:12]}.tmp")
    except OSError as exc:
        raise ConfigError(f"cannot write: {exc.strerror}", file=str(target)) from None
    try:
        write(tmp)
        if folder:
            _replace_folder(tmp, target)
        else:
            os.replace(tmp, target)
    except OSError as exc:
        _remove(tmp)
        raise ConfigError(f"cannot write: {exc.strerror or exc}", file=str(target)) from None
    except BaseException:
        _remove(tmp)
        raise
    return target


def _replace_folder(tmp: Path, target: Path) -> None:
    """A directory cannot replace a non-empty one in one rename: the old one is moved aside
    first, and moved back if the second rename fails."""
    if not target.exists():
        os.replace(tmp, target)
        return
    old = Path(tempfile.mkdtemp(prefix=f".{target.name}.old.", dir=target.parent))
    try:
        os.replace(target, old)  # onto the empty directory just made: a name no one else uses
    except OSError:
        old.rmdir()
        raise
    try:
        os.replace(tmp, target)
    except OSError:
        os.replace(old, target)
        raise
    shutil.rmtree(old, ignore_errors=True)


def _remove(tmp: Path) -> None:
    if tmp.is_dir() and not tmp.is_symlink():
        shutil.rmtree(tmp, ignore_errors=True)
    else:
        tmp.unlink(missing_ok=True)


def check_writable(target: Path | str, *, folder: bool) -> None:
    """ConfigError naming `target` unless a run could write it: `folder` — a folder that exists
    or can be made (its nearest existing ancestor is a folder we can write in); otherwise a file
    whose folder exists and can be written. Asked before a command starts anything, so a run of
    minutes does not end on a path it could never write (`--output /proc/x`, a read-only
    folder). Tried, not deduced from permission bits: root passes every `os.access` check, yet
    cannot write in /sys or on a read-only mount."""
    target = Path(target)
    if folder:
        where = target
        while not where.exists() and where != where.parent:
            where = where.parent
        if not where.is_dir():
            raise ConfigError(f"{where} is not a folder", file=str(target))
    else:
        where = target.parent if str(target.parent) else Path(".")
        if target.is_dir():
            raise ConfigError("is a folder, not a file", file=str(target))
        if not where.is_dir():
            raise ConfigError(f"folder {where} does not exist", file=str(target))
    try:
        fd, probe = tempfile.mkstemp(prefix=".mrta-probe-", dir=where)
    except OSError as exc:
        raise ConfigError(f"cannot write in {where}: {exc.strerror}", file=str(target)) from None
    os.close(fd)
    os.unlink(probe)


def save_figure(fig, output: Path | str) -> Path:
    """A matplotlib figure to `output` as PNG, atomically; ConfigError if it cannot be written."""
    return write_atomically(output, lambda tmp: fig.savefig(tmp, format="png"))


def write_text(output: Path | str, text: str) -> Path:
    """UTF-8 text to `output`, atomically; ConfigError if it cannot be written."""
    return write_atomically(output, lambda tmp: tmp.write_text(text, encoding="utf-8"))


def write_folder(folder: Path | str, files: Mapping[str, bytes], *,
                 modes: Mapping[str, int] | None = None) -> list[Path]:
    """Every file of `files` (relative path → content) into `folder`, replacing the folder and
    all it held — or nothing at all. `modes` gives some files permissions (0o600 for a private
    key), set before the folder appears, so no one can read a key in between."""
    folder = Path(folder)
    modes = modes or {}

    def fill(tmp: Path) -> None:
        for rel, data in files.items():
            path = tmp / rel
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_bytes(data)
            if rel in modes:
                os.chmod(path, modes[rel])

    write_atomically(folder, fill, folder=True)
    return [folder / rel for rel in files]
