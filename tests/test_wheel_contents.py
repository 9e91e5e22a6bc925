"""What the wheel holds, read off pyproject.toml: every package folder of the project is listed in
`packages` (setuptools leaves an unlisted one out of the wheel, and a user's run fails only
when something imports it), and every file beside a package's modules that is not Python is
matched by that package's `package-data` (else it is left out too: a launch, a parameter file,
a world). `.ci/wheel` then runs one demo from the built wheel in an empty folder — what only a
run proves (entry points, plotting, data found through the installed packages, not the
source tree); this test proves, for every application and architecture at once and in
milliseconds, what a demo of each would have had to find."""

from __future__ import annotations

import os
import tomllib
from fnmatch import fnmatch
from functools import cache
from pathlib import Path

from tests.harness.helpers import ROOT

SETUPTOOLS = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
PACKAGE_DIR: dict[str, str] = SETUPTOOLS["package-dir"]
PACKAGES: list[str] = SETUPTOOLS["packages"]
PACKAGE_DATA: dict[str, list[str]] = SETUPTOOLS["package-data"]


def folder_of(package: str) -> Path:
    """The package's folder: its own package-dir entry, or its longest listed parent's."""
    parts = package.split(".")
    for n in range(len(parts), 0, -1):
        base = PACKAGE_DIR.get(".".join(parts[:n]))
        if base is not None:
            return ROOT.joinpath(base, *parts[n:])
    return ROOT.joinpath(*parts)


@cache
def files() -> list[Path]:
    """Every file below the folders the wheel is made from (each top-level package's, and
    configs/: a new application's folder is a top-level package of its own), bytecode aside."""
    out = []
    for root in {*(folder_of(p) for p in PACKAGES if "." not in p), ROOT / "configs"}:
        for folder, subfolders, names in os.walk(root):
            subfolders[:] = [d for d in subfolders if d != "__pycache__"]
            out += [Path(folder, n) for n in names if not n.endswith(".pyc")]
    return out


@cache
def package_folders() -> frozenset[Path]:
    return frozenset(f.parent for f in files() if f.name == "__init__.py")


def test_every_package_folder_is_listed_and_every_listed_package_is_a_folder():
    listed, found = {folder_of(p): p for p in PACKAGES}, package_folders()
    assert set(listed) - found == set(), sorted(listed[f] for f in set(listed) - found)
    unlisted = sorted(str(f.relative_to(ROOT)) for f in found - set(listed))
    assert unlisted == [], f"package folders missing from pyproject.toml's packages: {unlisted}"


def data_files() -> dict[str, list[str]]:
    """Each listed package's files that are not Python, relative to its folder (a file belongs
    to the nearest package folder above it)."""
    package = {folder_of(p): p for p in PACKAGES}
    out: dict[str, list[str]] = {p: [] for p in PACKAGES}
    for f in files():
        if f.suffix == ".py":
            continue
        owner = next((d for d in f.parents if d in package), None)
        if owner is not None:
            out[package[owner]].append(f.relative_to(owner).as_posix())
    return out


def test_every_data_file_of_a_package_is_in_its_package_data():
    data = data_files()
    missing = {p: [f for f in files if not any(fnmatch(f, g) and f.count("/") == g.count("/")
                                               for g in PACKAGE_DATA.get(p, []))]
               for p, files in data.items()}
    assert {p: m for p, m in missing.items() if m} == {}, "not in the wheel (package-data)"
    # and the check sees the files: every application ships its launches and parameter files
    apps = [p for p in PACKAGES if p.startswith(("mrta_patrol", "mrta_delivery"))]
    assert len(apps) >= 8 and all(any(f.startswith("launch/") for f in data[p]) and
                                  any(f.startswith("config/") for f in data[p]) for p in apps)
