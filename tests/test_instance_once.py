"""One copy of an instance per package, read once per process (mrta_agent.runtime.instance):
the layers file names the package's `config/instance.yaml` instead of embedding it, an SSI or
CBBA robot and its layers read that one file once, and a robot file and a layers file that
name different instances are refused before anything runs."""

from __future__ import annotations

import shutil
from collections import Counter
from pathlib import Path

import pytest

import mrta_zenoh.yamlfile as yamlfile
from mrta_agent.runtime.host import AgentOptions
from mrta_zenoh.architectures import architecture
from mrta_zenoh.errors import ConfigError
from tests.harness.helpers import CONFIGS

APPS = CONFIGS / "applications"
PACKAGES = {"alliance": "delivery", "murdoch": "delivery_murdoch",
            "central": "delivery_central", "ssi": "delivery_ssi", "cbba": "delivery_cbba",
            "tessi": "delivery_tessi"}


@pytest.fixture
def reads(monkeypatch) -> Counter:
    """How often each file is read through the strict YAML reader (every parameter and
    instance file is)."""
    counts: Counter = Counter()
    real = yamlfile.read_bounded

    def counting(path, what):
        counts[Path(path).resolve()] += 1
        return real(path, what)

    monkeypatch.setattr(yamlfile, "read_bounded", counting)
    return counts


def options(config: Path, arch: str, robot: str = "robot1") -> AgentOptions:
    return AgentOptions(robot, config / f"{robot}_{arch}_params.yaml",
                        config / f"tasks_{arch}_params.yaml", config / f"layers_{arch}_params.yaml")


@pytest.mark.parametrize("arch", sorted(PACKAGES))
def test_a_robot_reads_its_packages_instance_once_and_its_plugins_see_it(arch, reads):
    config = APPS / PACKAGES[arch] / "config"
    prepared = architecture(arch).prepare(options(config, arch))
    assert reads[(config / "instance.yaml").resolve()] == 1
    instance = prepared.plugins.instance
    assert instance.path.resolve() == (config / "instance.yaml").resolve()
    assert sorted(instance.doc.tasks) == ["t1", "t2", "t3", "t4"]
    assert prepared.plugins.unread_warnings() == []  # `instance` is no section nobody reads


def test_the_mission_hook_reads_a_runs_instance_once(reads, tmp_path):
    """The task watch, the end of the run and the analysis each ask for the instance: the file
    is read once (again only when it changes)."""
    from mrta_delivery.mission import run_instance
    pkg = tmp_path / "delivery_ssi"
    shutil.copytree(APPS / "delivery_ssi", pkg)

    class Run:
        layers_params = pkg / "config" / "layers_ssi_params.yaml"

    first = [run_instance(Run()) for _ in range(3)]
    instance = (pkg / "config" / "instance.yaml").resolve()
    assert reads[instance] == 1 and first[0] is first[2]
    text = instance.read_text().replace("service: 4.0", "service: 6.0")
    instance.write_text(text + "\n")
    assert run_instance(Run()).task("t1").service == 6.0 and reads[instance] == 2


def copy(tmp_path: Path, package: str) -> Path:
    shutil.copytree(APPS / package, tmp_path / package)
    return tmp_path / package / "config"


def test_a_robot_planning_on_one_instance_and_driving_to_another_is_refused(tmp_path):
    config = copy(tmp_path, "delivery_ssi")
    shutil.copy(config / "instance.yaml", config / "other.yaml")
    layers = config / "layers_ssi_params.yaml"
    layers.write_text(layers.read_text().replace("instance: instance.yaml",
                                                 "instance: other.yaml"))
    with pytest.raises(ConfigError, match="a robot plans on and drives to one instance"):
        architecture("ssi").prepare(options(config, "ssi"))


def test_a_layers_file_naming_a_missing_instance_names_its_line(tmp_path):
    config = copy(tmp_path, "delivery")
    layers = config / "layers_alliance_params.yaml"
    layers.write_text(layers.read_text().replace("instance: instance.yaml",
                                                 "instance: nowhere.yaml"))
    with pytest.raises(ConfigError) as err:
        architecture("alliance").prepare(options(config, "alliance"))
    assert err.value.file == str(layers) and err.value.line == 3
    assert "nowhere.yaml does not exist" in str(err.value)


def test_a_delivery_robot_whose_layers_name_no_instance_is_refused_before_it_runs(tmp_path):
    config = copy(tmp_path, "delivery_murdoch")
    layers = config / "layers_murdoch_params.yaml"
    layers.write_text(layers.read_text().replace("instance: instance.yaml\n", ""))
    with pytest.raises(ConfigError, match="reads the robot's instance: name its file"):
        architecture("murdoch").prepare(options(config, "murdoch"))


def numbers(value) -> list[tuple[float, float]]:
    """Every point a parsed YAML value holds: a pair of numbers, or a mapping with x and y."""
    out = []
    if isinstance(value, dict):
        if {"x", "y"} <= set(value):
            out.append((value["x"], value["y"]))
        for v in value.values():
            out += numbers(v)
    elif isinstance(value, list):
        if len(value) == 2 and all(isinstance(v, (int, float)) for v in value):
            out.append(tuple(value))
        for v in value:
            out += numbers(v)
    return out


def xml_points(text: str) -> set[tuple[float, float]]:
    """The points an rqt_mrta.xml states: an element whose parameters include `x` and `y`."""
    import xml.etree.ElementTree as ET
    out = set()
    for el in ET.fromstring(text).iter():
        values = {c.findtext("name"): c.findtext("value") for c in el
                  if c.findtext("name") in ("x", "y") and c.findtext("value") is not None}
        if len(values) == 2:
            out.add((float(values["x"]), float(values["y"])))
    return out


DELIVERY_PACKAGES = sorted(p for p in APPS.iterdir()
                           if p.is_dir() and (p / "config" / "instance.yaml").is_file()
                           and p.name.startswith("delivery"))


def test_every_delivery_package_in_configs_is_checked():
    assert {p.name for p in DELIVERY_PACKAGES} == {f"delivery{s}" for s in
                                                   ("", "_murdoch", "_central", "_ssi", "_cbba",
                                                    "_tessi")}


@pytest.mark.parametrize("package", DELIVERY_PACKAGES, ids=lambda p: p.name)
def test_a_delivery_packages_task_positions_appear_in_one_of_its_files_only(package):
    """The done-when of issue 46.7: every file of the package but its Python modules (parameter
    files, launch files, rqt_mrta.xml, the world) is read — YAML as data, points as pairs or
    x/y mappings; the others as text, a point as `x,y` or `x, y` — and only config/instance.yaml
    holds a task's position."""
    import yaml
    tasks = yaml.safe_load((package / "config" / "instance.yaml").read_text())["tasks"]
    positions = {tuple(map(float, t["position"])) for t in tasks.values()}
    assert positions
    holding = set()
    for f in sorted(package.rglob("*")):
        if not f.is_file() or f.suffix in (".py", ".pyc"):
            continue
        text = f.read_text()
        if f.suffix == ".yaml":
            found = {tuple(map(float, p)) for p in numbers(yaml.safe_load(text))}
        else:  # launch files: a point written out; rqt_mrta.xml: x/y parameter pairs too
            found = {p for p in positions
                     if any(sep.join(f"{c:g}" for c in p) in text for sep in (",", ", "))}
            if f.suffix == ".xml":
                found |= xml_points(text)
        if found & positions:
            holding.add(f.relative_to(package).as_posix())
    assert holding == {"config/instance.yaml"}
