"""The robot's instance: the one file of its package that states the problem (robots, tasks,
world), named by the layers file's top-level `instance` key (a path relative to that file) and
read once per process.

Why a name and not the content: an instance written into every file that needs it (the layers
file once embedded a full copy beside `config/instance.yaml`) drifts — edit one copy and the
robots plan on one problem while their layers drive to another. Now a package holds its
instance once; the layers file, an own-route robot file (SSI, CBBA: the instance their decision
logic plans on) and central's dispatcher name that file. A robot whose robot file and layers
file name different files is refused before anything runs.

Plugins read the document as `ctx.instance` (a plugin declaring `instance_type` is refused at
load when its robot's layers file names none); the runtime reads the file through the core's
instance registry (`mrta_zenoh.instances`), so the document is the application's typed one.
"""

from __future__ import annotations

from pathlib import Path

from mrta_zenoh import instances
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.yamlfile import YamlDoc

KEY = "instance"  # the layers file's one top-level key that is not a section


def named_instance(layers: YamlDoc | None) -> Path | None:
    """The instance file the layers file names (None: it names none), which must exist."""
    if layers is None or KEY not in layers.data:
        return None
    value = layers.data[KEY]
    if not isinstance(value, str) or not value.strip():
        raise layers.error((KEY,), f"{KEY} must name the instance file (relative to this "
                           f"file), got {value!r:.40}")
    path = Path(layers.path).parent / value
    if not path.is_file():
        raise layers.error((KEY,), f"its instance file {path} does not exist")
    return path


def read_instance(layers: YamlDoc | None) -> instances.Loaded | None:
    """The instance the layers file names, read and checked (None: it names none)."""
    path = named_instance(layers)
    return None if path is None else instances.load(path)


def same_instance(planned: Path, layers: YamlDoc | None, robot_file: Path | str) -> None:
    """An own-route robot plans on `planned` (its robot file's `instance`); its layers, when
    their file names an instance, must drive to the same one."""
    driven = named_instance(layers)
    if driven is not None and driven.resolve() != Path(planned).resolve():
        raise ConfigError(f"{robot_file}: its instance {planned} is not the one its layers "
                          f"file {layers.path} names ({driven}): a robot plans on and drives "
                          "to one instance")
