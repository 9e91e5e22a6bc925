"""What is installed: a group's entry points, read once per import path.

`importlib.metadata.entry_points()` reads every installed distribution's metadata at each call
(≈ 10 ms with a hundred distributions, far more on a loaded machine). The CLI, the package
registry, the instance generators, the architectures, the missions and the plugins each asked
again at every use: a robot loaded one evaluator per task, and one test process asked hundreds
of times (a fifth of the CPU of the suite's instance and experiment tests). Read once per
import path: a distribution put on the path later (a plugin folder, a test's dist-info) is
seen, as importlib would see it."""

from __future__ import annotations

import functools
import sys
from importlib import metadata


@functools.lru_cache(maxsize=4)
def _installed(path: tuple[str, ...]) -> metadata.EntryPoints:
    return metadata.entry_points()


@functools.lru_cache(maxsize=64)
def _group(group: str, path: tuple[str, ...]) -> metadata.EntryPoints:
    return _installed(path).select(group=group)


def entry_points(group: str) -> metadata.EntryPoints:
    """The entry points registered under `group` (`.select(name=...)` narrows them)."""
    return _group(group, tuple(sys.path))


@functools.lru_cache(maxsize=512)
def _name(dist: metadata.Distribution) -> str:
    return dist.name


def distribution_name(ep: metadata.EntryPoint) -> str:
    """The name of the distribution that registers `ep` ("?" when unknown). Reading it parses
    that distribution's metadata: once per distribution (the package registry names one for
    each package it finds, at every registry built)."""
    return _name(ep.dist) if ep.dist is not None else "?"


def forget() -> None:
    """Read them again at the next call (a test that counts the reads)."""
    _name.cache_clear()
    _group.cache_clear()
    _installed.cache_clear()
