"""Which code made a row of results.csv: its `code` column (issue 48).

A study is run over days of commits, and a fix to an architecture changes what its runs
measure; a row that does not say which code made it can be told apart from a row of the fixed
code only by a hand-kept list (docs/study/README.md, "Which code made the rows", for the rows
made before this column). So every row names the code of the process that started its run:

- `1a2b3c4d5e6f` — the git commit (12 hex digits) of the checkout this package runs from,
  when the project's code in it (CODE: its packages and pyproject.toml) is that commit's;
- `1a2b3c4d5e6f+dirty` — the same checkout with uncommitted changes to that code (rows made
  by code no commit holds: not to be published as a commit's);
- `mrta-zenoh 0.1.0` — an installed distribution, not a checkout (a wheel carries no commit).

Only the code counts: a checkout whose docs/study rows are being written (`run.sh` into its
own docs/study) is not dirty for that. A blank cell is a row made before the column existed:
see the README's list. The value is read once per process (`code_revision` is cached): the
local backend's runs are forked from a server that imported the code when the experiment
started, so the revision at start is theirs; a Dask or SLURM task reads its own machine's.
"""

from __future__ import annotations

import functools
import hashlib
import os
import struct
from importlib import metadata
from pathlib import Path

import mrta_zenoh

CODE_COLUMN = "code"
DIRTY = "+dirty"
UNCHECKED = "+unchecked"  # the commit is known, the code's state against it could not be read
DISTRIBUTION = "mrta-zenoh"
# what decides a run's rows: the top-level packages (fixed: docs/architecture.md) and the
# file that declares their entry points; not docs/, tests/ or benchmarks/
CODE = ("mrta_zenoh", "robot_agent", "supervisor", "simulator", "configs", "pyproject.toml")
SHORT = 12  # hex digits of the commit


def checkout_of(package: Path) -> Path | None:
    """The git checkout whose top level holds `package` (a folder), or None: an installed
    distribution."""
    root = package.resolve().parent
    return root if (root / ".git").exists() else None


def revision_of(root: Path) -> str | None:
    """The `code` value of the checkout at `root` (module docstring); None when its git data
    cannot be read. Read from git's own files, not by running git: an experiment's process
    starts no other process but its runs (and the tests' stand-in runs none)."""
    try:
        git = _git_dir(root)
        head = _head(git)
    except (OSError, ValueError):
        return None
    try:
        changed = _changed(root, git / "index", len(head) // 2)
    except (OSError, ValueError, struct.error):
        return head[:SHORT] + UNCHECKED
    return head[:SHORT] + (DIRTY if changed else "")


@functools.cache
def code_revision() -> str:
    """This process's `code` value (module docstring)."""
    root = checkout_of(Path(mrta_zenoh.__file__).parent)
    revision = revision_of(root) if root is not None else None
    if revision is not None:
        return revision
    return f"{DISTRIBUTION} {metadata.version(DISTRIBUTION)}"


def revisions(rows: list[dict[str, str]]) -> dict[str, int]:
    """How many rows each code made, by `code` value ("": rows from before the column), in
    sorted order: what a report says of its rows' provenance."""
    counts: dict[str, int] = {}
    for row in rows:
        key = row.get(CODE_COLUMN) or ""
        counts[key] = counts.get(key, 0) + 1
    return dict(sorted(counts.items()))


# ------------------------------------------------------------------ git's files
def _git_dir(root: Path) -> Path:
    """The checkout's git folder: `.git`, or where a worktree's `.git` file points."""
    dot = root / ".git"
    if dot.is_dir():
        return dot
    text = dot.read_text().strip()
    if not text.startswith("gitdir:"):
        raise ValueError(f"{dot}: not a gitdir link")
    return (root / text.removeprefix("gitdir:").strip()).resolve()


def _common(git: Path) -> Path:
    """Where refs and objects live: a worktree's `commondir`, else the git folder itself."""
    link = git / "commondir"
    return (git / link.read_text().strip()).resolve() if link.is_file() else git


def _head(git: Path) -> str:
    """HEAD's commit, in hex: detached, a loose ref, or a packed one."""
    head = (git / "HEAD").read_text().strip()
    if not head.startswith("ref:"):
        return _hex(head)
    ref = head.removeprefix("ref:").strip()
    for folder in (git, _common(git)):
        loose = folder / ref
        if loose.is_file():
            return _hex(loose.read_text().strip())
    packed = _common(git) / "packed-refs"
    for line in packed.read_text().splitlines() if packed.is_file() else []:
        sha, _, name = line.partition(" ")
        if name == ref:
            return _hex(sha)
    raise ValueError(f"HEAD names {ref}, which has no commit")


def _hex(text: str) -> str:
    if len(text) not in (40, 64) or any(c not in "0123456789abcdef" for c in text):
        raise ValueError(f"not a commit: {text[:70]!r}")
    return text


def _changed(root: Path, index: Path, size: int) -> bool:
    """Whether the checkout's code differs from its index — a tracked file changed or gone
    (what `git diff-files` says: the index's stat data first, the content's hash when they
    differ), or a Python module git does not track. Not seen: changes staged with `git add`
    but not committed (the index against HEAD's tree, which is compressed objects): the rows
    of such a checkout name HEAD."""
    entries = _index_entries(index.read_bytes(), size)
    algo = hashlib.sha1 if size == 20 else hashlib.sha256
    tracked = set()
    for path, (mtime, length, sha) in entries.items():
        if not path.startswith(CODE_DIRS) and path not in CODE:
            continue
        tracked.add(path)
        try:
            st = os.stat(root / path)
        except FileNotFoundError:
            return True
        if st.st_size != length:
            return True
        if divmod(st.st_mtime_ns, 10**9) == mtime:
            continue  # git's own fast path: unchanged since the index saw it
        blob = (root / path).read_bytes()
        if algo(b"blob %d\0" % len(blob) + blob).digest() != sha:
            return True
    return any(new.relative_to(root).as_posix() not in tracked
               for folder in CODE_DIRS for new in (root / folder).rglob("*.py"))


CODE_DIRS = tuple(f"{name}/" for name in CODE if "." not in name)


def _index_entries(data: bytes, size: int) -> dict[str, tuple[tuple[int, int], int, bytes]]:
    """git's index (versions 2–4, gitformat-index(5)): path → ((mtime s, ns), file size, blob
    hash of `size` bytes)."""
    if data[:4] != b"DIRC":
        raise ValueError("not a git index")
    version, count = struct.unpack(">II", data[4:12])
    if version not in (2, 3, 4):
        raise ValueError(f"git index version {version}")
    entries, at, previous = {}, 12, b""
    for _ in range(count):
        start = at
        mtime = struct.unpack(">II", data[at + 8:at + 16])
        length = struct.unpack(">I", data[at + 36:at + 40])[0]
        sha = data[at + 40:at + 40 + size]
        flags = struct.unpack(">H", data[at + 40 + size:at + 42 + size])[0]
        at += 42 + size + (2 if version >= 3 and flags & 0x4000 else 0)
        if version == 4:  # the previous path less N bytes, then a suffix; no padding
            byte = data[at]
            strip = byte & 0x7F
            while byte & 0x80:
                at += 1
                byte = data[at]
                strip = ((strip + 1) << 7) | (byte & 0x7F)
            end = data.index(b"\0", at + 1)
            path = previous[:len(previous) - strip] + data[at + 1:end]
            at = end + 1
        else:  # NUL-terminated, padded with NULs to a multiple of 8 bytes from the entry's start
            end = data.index(b"\0", at)
            path = data[at:end]
            at = start + (end - start + 8) // 8 * 8
        previous = path
        entries[path.decode()] = (mtime, length, sha)
    return entries
