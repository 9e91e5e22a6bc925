"""Parameter overrides: `GLOB.KEY.PATH` = value, set in an application package's parameter
files (config/*.yaml) — an experiment's `overrides:` (experiment/file.py) and `mrta demo
--override` alike.

GLOB matches a file's stem, or its stem up to the architecture's suffix (`robot*` matches
robot1_alliance_params.yaml); KEY.PATH walks the file's mappings and must name a key the file
already has (an override never adds a parameter the agent would not read). A key matching no
file, or a path missing from a file it matches, is a ConfigError naming both: an override that
silently did nothing would make every run of its cell a copy of the default's.

Where they are applied: a run without an instance gets its own copy of the installed package
(runs.package_copy); a run of an instance (`mrta demo --instance`) derives its
packages into its own folder, and the overrides are applied there, after the derivation
(mission.run_mission) — the installed packages are never written.
"""

from __future__ import annotations

import fnmatch
from pathlib import Path
from typing import Any

import yaml

from mrta_zenoh.errors import ConfigError
from mrta_zenoh.files import write_text

Overrides = tuple[tuple[str, Any], ...]


def _set_path(data: dict, path: list[str], value: Any, where: str) -> None:
    d = data
    for i, p in enumerate(path[:-1]):
        if not isinstance(d, dict) or p not in d:
            raise ConfigError(f"override {where}: no key {'.'.join(path[:i + 1])!r}")
        d = d[p]
    if not isinstance(d, dict) or path[-1] not in d:
        raise ConfigError(f"override {where}: no key {'.'.join(path)!r}")
    d[path[-1]] = value


def apply_overrides(package: Path, overrides: Overrides) -> None:
    """Set every override in the parameter files of the package at `package` (a copy or a
    run's derived package: never an installed one)."""
    for key, value in overrides:
        glob, _, dotted = key.partition(".")
        files = [f for f in sorted((package / "config").glob("*.yaml"))
                 if fnmatch.fnmatch(f.stem, glob) or fnmatch.fnmatch(f.stem, glob + "_*")]
        if not files:
            raise ConfigError(f"override {key}: no parameter file of package "
                              f"{package.name!r} matches {glob!r}", file=str(package / "config"))
        for f in files:
            data = yaml.safe_load(f.read_text())
            _set_path(data, dotted.split("."), value, f"{key} in {f.name}")
            write_text(f, yaml.safe_dump(data, sort_keys=False))


def override_text(key: str, value: Any) -> str:
    """`KEY=VALUE` for `mrta demo --override`, VALUE in YAML flow style, so `parse_override`
    gives back the same value and type (2.0 stays a float, "2" a string)."""
    dumped = yaml.safe_dump(value, default_flow_style=True, width=10**9).strip()
    return f"{key}={dumped.removesuffix('...').strip()}"


def parse_override(text: str) -> tuple[str, Any]:
    """`GLOB.KEY.PATH=VALUE` (VALUE read as YAML: 2.0, true, [1, 2]); a ConfigError saying
    what is expected otherwise."""
    key, sep, raw = text.partition("=")
    key = key.strip()
    if not sep or "." not in key or not key.split(".", 1)[0] or not key.split(".", 1)[1]:
        raise ConfigError(f"--override {text!r}: expected FILE_GLOB.KEY.PATH=VALUE, e.g. "
                          "robot*.timeout_duration=4.0")
    try:
        return key, yaml.safe_load(raw)
    except yaml.YAMLError:
        raise ConfigError(f"--override {text!r}: the value is not YAML "
                          "(a number, true/false, a string, [a, list])") from None
