"""Where the project's shipped configuration lives (worlds, architecture and application packages).

The project is installed editable (see README), so `configs/` sits beside the packages; an
installed copy without it simply finds nothing there and relies on MRTA_PACKAGE_PATH and entry
points instead.
"""

from __future__ import annotations

from pathlib import Path

PROJECT_ROOT = Path(__file__).resolve().parent.parent
CONFIGS = PROJECT_ROOT / "configs"
WORLDS = CONFIGS / "worlds"


def bundled_world(name: str) -> Path | None:
    """`patrol` → configs/worlds/patrol.yaml, if it exists."""
    for suffix in (".yaml", ".yml", ".map"):
        p = WORLDS / f"{name}{suffix}"
        if p.is_file():
            return p
    return None
