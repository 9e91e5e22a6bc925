"""docs/architecture.md is the map of the code: its layout names every module of the core, the
simulator and the supervisor, and every module, file and dotted name it points at exists — a
renamed or removed module makes this fail until the map says so."""

from __future__ import annotations

import importlib
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "architecture.md"
MAPPED = ("mrta_zenoh", "simulator", "supervisor", "robot_agent")


def layout() -> str:
    text = DOC.read_text()
    start = text.index("## Pieces and layering")
    return text[text.index("```", start):text.index("```\n\n", start)]


def named_in_layout(folder: str) -> set[str]:
    """Module and package names the layout shows under `folder`."""
    lines, inside = [], False
    for line in layout().splitlines():
        top = re.match(r"^ (\S+)/", line)
        if top:
            inside = top.group(1) == folder
        if inside:
            lines.append(line)
    return set(re.findall(r"\b([a-z_0-9]+)(?:\.py\b|/)", "\n".join(lines)))


@pytest.mark.parametrize("folder", MAPPED)
def test_the_layout_names_every_module(folder):
    path = ROOT / folder
    modules = {p.stem for p in path.glob("*.py") if p.name != "__init__.py"}
    modules |= {p.name for p in path.iterdir() if (p / "__init__.py").is_file()}
    assert modules - named_in_layout(folder) == set()


def test_every_path_the_map_points_at_exists():
    text = DOC.read_text()
    paths = set(re.findall(r"\b((?:[a-z_]+/)+[a-z_0-9]+\.(?:py|md|toml))\b", text))
    missing = {p for p in paths if not (ROOT / p).exists()
               and not (ROOT / "configs" / "applications" / p).exists()}
    assert paths and missing == set()


def test_every_dotted_name_the_map_uses_resolves():
    names = set(re.findall(r"`(mrta_[a-z_]+(?:\.[A-Za-z_]+)*)(?![\w/])", DOC.read_text()))
    missing = set()
    for name in names:
        parts = name.split(".")
        for i in range(len(parts), 0, -1):
            try:
                obj = importlib.import_module(".".join(parts[:i]))
            except ImportError:
                continue
            try:
                for attr in parts[i:]:
                    obj = getattr(obj, attr)
            except AttributeError:
                missing.add(name)
            break
        else:
            missing.add(name)
    assert names and missing == set()
