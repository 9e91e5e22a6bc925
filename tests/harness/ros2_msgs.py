"""Vendored ROS 2 message definitions for the independent peer (zenoh-ros2-sdk), which would
otherwise download `.msg` files at run time: written from rosbags' Jazzy store — the same
definitions ROS 2 ships — into `<dir>/<package>/msg/<Name>.msg`, dependencies included. The SDK
computes type hashes from these files with its own code, so agreeing with it is a real check."""

from __future__ import annotations

from pathlib import Path

from rosbags.typesys import Stores, get_typestore
from rosbags.typesys.base import Nodetype


def _field_type(node: tuple) -> tuple[str, list[str]]:
    kind, spec = node
    if kind == Nodetype.BASE:
        name, bound = spec
        return (f"{name}<={bound}" if bound else name), []
    if kind == Nodetype.NAME:
        pkg, _, name = spec.split("/")
        return f"{pkg}/{name}", [spec]
    inner, size = spec
    text, deps = _field_type(inner)
    if kind == Nodetype.ARRAY:
        return f"{text}[{size}]", deps
    return (f"{text}[<={size}]" if size else f"{text}[]"), deps


def write_msgs(dest: Path, ros_types: list[str], distro=Stores.ROS2_JAZZY) -> Path:
    store = get_typestore(distro)
    todo, done = list(ros_types), set()
    while todo:
        t = todo.pop()
        if t in done:
            continue
        done.add(t)
        consts, fields = store.fielddefs[t]
        lines = [f"{ctype} {name}={value!r}".replace("'", '"') if ctype == "string"
                 else f"{ctype} {name}={value}" for name, ctype, value in consts]
        for name, node in fields:
            text, deps = _field_type(node)
            lines.append(f"{text} {name}")
            todo.extend(deps)
        pkg, _, name = t.split("/")
        f = dest / pkg / "msg" / f"{name}.msg"
        f.parent.mkdir(parents=True, exist_ok=True)
        f.write_text("\n".join(lines) + "\n")
    return dest
