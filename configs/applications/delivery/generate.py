"""The delivery application packages from one instance — ALLIANCE's `delivery`, MURDOCH's
`delivery_murdoch` and central's `delivery_central`: `python -m mrta_delivery.generate_cli
[--instance FILE] [--output DIR] [--arrivals poisson --rate R --seed S]` writes the shipped ones
(or copies elsewhere); `derive` writes a run's own into its folder (`mrta demo --instance FILE`).

The rqt_mrta files (package.xml, rqt_mrta.xml, the robots' parameter files, the tasks file, the
per-robot launch files; central's dispatcher file) come from the toolchain's own generator
(`mrta app new`'s `build_application`), fed with answers computed from the instance — central's
are also written as `delivery_central_answers.yaml` beside the packages, from which `mrta app
new --answers` makes the same files; every package's `config/instance.yaml` (the instance, its
one copy in the package: the layers file, SSI's and CBBA's robot files and central's dispatcher
name it), the layers file (naming it; its `Delivery` section is how the layer drives),
`launch/delivery_sim.launch` (the simulator with the instance's starts, one agent per robot of
the instance, and central's dispatcher) and, in the ALLIANCE package, `worlds/delivery.yaml`
(the instance's room and walls, the world the simulator loads by name) are written beside
them. The Python modules of
`mrta_delivery` are not touched. tests/test_delivery.py checks that the shipped packages are
exactly what this writes.

How the instance becomes each architecture's parameters (docs/delivery.md):

* ALLIANCE: one behaviour set per task the robot can serve, with impatience
  fast_rate = θ / (ρ · α · cost) per tick — the robot's motivation for a task reaches θ after
  α · cost seconds, so the cheapest (robot, task) pair activates first, its broadcast resets
  the others' motivation for that task, and the next cheapest pair follows: greedy assignment
  in order of cost, as L-ALLIANCE's learnt impatience would make it. A robot serves several
  tasks one after another (time-extended): a rate is fixed while its motivation grows, so the
  cost it is computed from is the robot's travel time to the task from where it may be when
  it next becomes free — its start or any other task it can serve, averaged (`where_it_will_be`).
  expected_duration (the patience φ teammates grant) is twice that cost and the service, plus
  10 s.
* MURDOCH: one skill per task the robot can serve (level 1) and utility
  1 − w · distance / speed (distance_weight = w / speed): bids are 1 − w · cost, so the
  auctioneer's greedy award is again the lowest cost first. Bids are priced from the robot's
  pose when it bids, so a robot that finished a task bids from there.
* central: one task entry per task the robot can serve (its evaluator), the dispatcher on
  MinSum with its defaults (robot_agent/central/params.py).
* SSI, CBBA and TeSSI (`delivery_ssi`, `delivery_cbba`, `delivery_tessi`, answers files beside
  central's): as central's robots, each robot file naming the package's `config/instance.yaml`,
  which its decision logic plans on; their own keys at their defaults.
"""

from __future__ import annotations

import dataclasses
import random
from pathlib import Path

import msgspec

from mrta_zenoh.architectures import TEAM_ENV
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.files import write_folder, write_text
from mrta_zenoh.seeds import SEED_ENV
from mrta_zenoh.toolchain.generator import Answers, build_application, dump_yaml
from mrta_zenoh.toolchain.registry import Registry

from .instance import (DeliveryParams, InstanceBody, InstanceDoc, document_data,
                       document_yaml, flow, load_document)

HERE = Path(__file__).resolve().parent
INSTANCE = HERE / "config" / "instance.yaml"  # the shipped packages' instance: this package's
THETA = 10.0          # ALLIANCE threshold
SPIN = 10.0           # Hz, both architectures' decision rate
ALPHA = 0.2           # s of ALLIANCE activation delay per s of travel cost
UTILITY_WEIGHT = 0.01  # MURDOCH: utility lost per s of travel cost
SENSORS = [{"plugin_name": "mrta/odometry", "topic_name": "odom",
            "timeout_duration": 2.0, "buffer_horizon": 2.0}]
EVALUATOR = "delivery/task_open"
COMMON = dict(version="1.0.0", maintainer="mrta-zenoh maintainers",
              email="maintainers@mrta-zenoh.dev", license="Apache-2.0")


def load_instance(path: Path = INSTANCE) -> InstanceBody:
    return load_document(path).body()


def with_poisson_arrivals(params: InstanceBody, rate: float, seed: int) -> InstanceBody:
    """The same robots and tasks with Poisson arrivals (rate tasks/s) drawn from `seed`'s own
    stream, in task order (the agents read the times from the file, never draw them)."""
    from .instances import poisson_arrivals
    if not rate > 0:
        raise ConfigError(f"--rate must be > 0, got {rate!r}")
    times = poisson_arrivals(random.Random(f"mrta.instances/poisson/{seed}"), rate,
                             len(params.tasks))
    tasks = {tid: msgspec.structs.replace(t, arrival=at)
             for (tid, t), at in zip(params.tasks.items(), times)}
    return msgspec.structs.replace(params, tasks=tasks)


def _costs(params: InstanceBody) -> dict[tuple[str, str], float]:
    """Each robot's travel time to each task from where it will be (`where_it_will_be`): the
    planning problem's travel times (around the walls when there are any)."""
    problem = params.problem()
    return {(r.id, t.id): where_it_will_be(problem, i, j) for i, r in enumerate(problem.robots)
            for j, t in enumerate(problem.tasks)}


def where_it_will_be(problem, i: int, j: int) -> float:
    """Robot i's travel time to task j from where it may be when it next becomes free: from
    its start, and — when the instance has more tasks than robots, so that robots serve several
    — from each other task it can serve, averaged. With no more tasks than robots every robot
    serves at most one in the greedy order, from its start: the IA rate, unchanged."""
    if len(problem.tasks) <= len(problem.robots):
        return problem.travel(i, None, j)
    places = [None] + [k for k in range(len(problem.tasks))
                       if k != j and problem.capable(i, k)]
    return sum(problem.travel(i, k, j) for k in places) / len(places)


def _sig(x: float) -> float:
    return float(f"{x:.4g}")


def _robot_tasks(params: InstanceBody) -> dict[str, list[str]]:
    out = {rid: [tid for tid in params.tasks if params.capable(rid, tid)]
           for rid in params.robots}
    idle = [rid for rid, tasks in out.items() if not tasks]
    if idle:
        raise ConfigError(f"robots {', '.join(idle)} can serve no task of the instance "
                          "(an rqt_mrta robot needs at least one task)")
    return out


def _tasks_list(params: InstanceBody, murdoch: bool) -> list[dict]:
    """The tasks file's entries. MURDOCH's name no `locations`: its robots price a task where
    the instance (the package's one copy) places it (mrta_agent.murdoch.architecture.located)."""
    out = []
    for tid in params.tasks:
        task = {"id": tid, "name": f"Delivery {tid}"}
        if murdoch:
            task["resources"] = [{"topic_name": "odom"}]
        task["layers"] = [{"plugin_name": "delivery/deliver"}]
        out.append(task)
    return out


def alliance_answers(params: InstanceBody, package: str = "delivery") -> Answers:
    robots = _robot_tasks(params)
    costs = _costs(params)
    per_robot = {}
    for k, (rid, tasks) in enumerate(robots.items()):
        sets = []
        for tid in tasks:
            cost = costs[(rid, tid)]
            expected = round(2.0 * (cost + params.task(tid).service) + 10.0, 1)
            sets.append({
                "task_expected_duration": expected,
                "motivational_behaviour": {
                    "threshold": THETA,
                    "acquiescence": {"yielding_delay": 3.0,
                                     "giving_up_delay": round(3.0 * expected, 1)},
                    "impatience": {"fast_rate": _sig(THETA / (SPIN * ALPHA * max(cost, 0.05)))},
                    "sensory_feedback": {"plugin_name": EVALUATOR,
                                         "sensors": [{"topic_name": "odom"}]}}})
        per_robot[rid] = {"name": f"Robot {k + 1}", "spin_rate": SPIN, "broadcast_rate": 2.0,
                          "timeout_duration": 2.0, "sensors": SENSORS, "behaviour_sets": sets}
    return Answers(package=package, name="Delivery", architecture="alliance", robots=robots,
                   configs={"alliance_params": per_robot,
                            "tasks_alliance_params": {"tasks": _tasks_list(params, False)}},
                   description="Point-task delivery (ST-SR-IA) with ALLIANCE: robots of "
                               "different speeds and capabilities, an optimal baseline.",
                   depends=["simulator", "supervisor"]
                   + (["delivery"] if package != "delivery" else []), **COMMON)


def central_answers(params: InstanceBody, package: str = "delivery_central") -> Answers:
    robots = _robot_tasks(params)
    per_robot = {}
    for k, (rid, tasks) in enumerate(robots.items()):
        per_robot[rid] = {
            "name": f"Robot {k + 1}", "spin_rate": SPIN, "report_period": 1.0, "lease": 3.0,
            "pose_topic": "odom", "sensors": SENSORS,
            "tasks": [{"evaluator": {"plugin_name": EVALUATOR,
                                     "sensors": [{"topic_name": "odom"}]}} for _ in tasks]}
    return Answers(package=package, name="Delivery (central)", architecture="central",
                   robots=robots,
                   configs={"central_params": per_robot,
                            "tasks_central_params": {"tasks": _tasks_list(params, False)},
                            "dispatcher_central_params": {"objective": "minsum"}},
                   description="Point-task delivery (ST-SR-TA) with a central dispatcher "
                               "re-solving the routing problem: robots of different speeds and "
                               "capabilities, each serving a queue.",
                   depends=["simulator", "supervisor", "delivery"], **COMMON)


OWN_ROUTE = {  # SSI and CBBA: each robot plans on the instance itself
    "ssi": ("SSI", "sequential single-item auctions: each round every robot bids the travel "
                   "time its best open task adds to its path, the lowest bid wins"),
    "tessi": ("TeSSI", "TeSSI's temporal auctions: each round every robot bids the makespan "
                       "its temporal network would have with its best open task inserted where "
                       "the network stays consistent, the lowest bid wins"),
    "cbba": ("CBBA", "the consensus-based bundle algorithm: each robot builds a bundle by "
                     "discounted reward and agrees on the winners with its teammates")}


def own_route_answers(params: InstanceBody, arch: str, package: str) -> Answers:
    """SSI's or CBBA's answers: one task entry per task the robot can serve (its evaluator),
    the instance beside the robot files (`config/instance.yaml`), the defaults otherwise."""
    robots = _robot_tasks(params)
    title, how = OWN_ROUTE[arch]
    per_robot = {}
    for k, (rid, tasks) in enumerate(robots.items()):
        per_robot[rid] = {
            "name": f"Robot {k + 1}", "spin_rate": SPIN, "report_period": 1.0,
            "pose_topic": "odom", "instance": "instance.yaml", "sensors": SENSORS,
            "tasks": [{"evaluator": {"plugin_name": EVALUATOR,
                                     "sensors": [{"topic_name": "odom"}]}} for _ in tasks]}
    return Answers(package=package, name=f"Delivery ({title})", architecture=arch,
                   robots=robots,
                   configs={f"{arch}_params": per_robot,
                            f"tasks_{arch}_params": {"tasks": _tasks_list(params, False)}},
                   description=f"Point-task delivery (ST-SR-TA) with {how}: robots of "
                               "different speeds and capabilities, each serving its path.",
                   depends=["simulator", "supervisor", "delivery"], **COMMON)


def answers_yaml(answers: Answers) -> bytes:
    """An answers file (`mrta app new --answers`) holding `answers`."""
    head = (f"# Answers for `mrta app new --answers`: the rqt_mrta files of "
            f"configs/applications/{answers.package}\n# (written by `python -m "
            "mrta_delivery.generate_cli` from config/instance.yaml; docs/delivery.md). The "
            "package also holds\n# the layers file, its delivery_sim.launch and the instance "
            "the robots serve,\n# which the generator writes beside these.\n")
    body = {"package": answers.package, "name": answers.name, "version": answers.version,
            "description": answers.description, "maintainer": answers.maintainer,
            "email": answers.email, "license": answers.license,
            "architecture": answers.architecture, "depends": answers.depends,
            "robots": answers.robots, "configs": answers.configs}
    return (head + dump_yaml(body, width=100)).encode()


def murdoch_answers(params: InstanceBody, package: str = "delivery_murdoch") -> Answers:
    robots = _robot_tasks(params)
    per_robot = {}
    for k, (rid, tasks) in enumerate(robots.items()):
        speed = params.robot(rid).speed
        per_robot[rid] = {
            "name": f"Robot {k + 1}", "spin_rate": SPIN, "bid_window": 0.5,
            "renewal_period": 0.5, "lease_timeout": 2.0, "reannounce_period": 2.0,
            "give_up_delay": 3.0, "pose_topic": "odom",
            "utility": {"skill_weight": 1.0, "distance_weight": _sig(UTILITY_WEIGHT / speed)},
            "sensors": SENSORS,
            "skills": [{"level": 1.0, "progress": {"plugin_name": EVALUATOR,
                                                   "sensors": [{"topic_name": "odom"}]}}
                       for _ in tasks]}
    return Answers(package=package, name="Delivery (MURDOCH)", architecture="murdoch",
                   robots=robots,
                   configs={"murdoch_params": per_robot,
                            "tasks_murdoch_params": {"tasks": _tasks_list(params, True)}},
                   description="Point-task delivery (ST-SR-IA) with MURDOCH auctions: robots "
                               "of different speeds and capabilities, an optimal baseline.",
                   depends=["simulator", "supervisor", "delivery"], **COMMON)


def layers_yaml(stem: str) -> bytes:
    """The layers file: the instance file it names (the package's one copy, beside it) and how
    the delivery layer drives (DeliveryParams, at its defaults)."""
    head = (f"# layers_{stem}_params: the delivery layers' parameters (written by `python -m "
            "mrta_delivery.generate_cli`; docs/delivery.md)\n")
    driving = msgspec.to_builtins(DeliveryParams())
    return (head + "# the instance the robots serve, relative to this file\n"
            "instance: instance.yaml\n"
            "Delivery:\n" + "".join(f"  {k}: {flow(v)}\n" for k, v in driving.items())
            ).encode()


def world_yaml(params: InstanceBody) -> bytes:
    """The simulator's world (docs/worlds.md): the instance's room and walls. Its tasks are no
    markers here: the launch file gives the simulator the package's instance (`--markers`),
    which states where they are once."""
    w, h = params.world.size
    room = [[-w / 2, -h / 2], [w / 2, -h / 2], [w / 2, h / 2], [-w / 2, h / 2]]
    head = (f"# The delivery world: a {w:g} m × {h:g} m room"
            + (f" with {len(params.world.walls)} walls inside" if params.world.walls
               else ", open")
            + " (written by mrta_delivery.generate from the instance; docs/delivery.md).\n"
            "# Starts come from the instance (the launch file's --robot options), and so do the\n"
            "# tasks the snapshot marks (its --markers option).\n")
    lines = ["name: delivery", "walls:", f"  - polygon: {flow(room)}"]
    lines += [f"  - segment: {flow(list(map(float, wall)))}" for wall in params.world.walls]
    return (head + "\n".join(lines) + "\n").encode()


def sim_launch(params: InstanceBody, package: str, arch_pkg: str, stem: str,
               dispatcher: bool = False) -> bytes:
    starts = " ".join(f"--robot {rid}={r.start[0]:g},{r.start[1]:g},{r.heading:g}"
                      for rid, r in params.robots.items())
    lines = [
        '<?xml version="1.0"?>',
        f"<!-- The delivery mission under {arch_pkg}: the world, the instance's robots at their",
        "     starts, one agent each on simulation time (written by `python -m",
        f"     mrta_delivery.generate_cli`). mrta launch {package} delivery_sim.launch -->",
        "<launch>",
        '  <arg name="speed" default="1"/>',
        '  <arg name="seed" default="0"/>',
        '  <arg name="sim_args" default="" doc="extra options for mrta sim, e.g. --duration 60"/>',
        "  <!-- the application's robots: the only teammates its agents count (their team "
        "option) -->",
        f'  <env name="{TEAM_ENV}" value="{",".join(params.robots)}"/>',
        "  <!-- the run's seed, for every node of it (their seed option; a node started by the "
        "mission runner gets it from the runner too) -->",
        f'  <env name="{SEED_ENV}" value="$(arg seed)"/>',
        "  <!-- the simulator is required: the launch ends when it does -->",
        '  <node name="sim" pkg="simulator" type="sim" required="true"',
        f'        args="--world delivery {starts} --markers $(find {package})/config/instance.yaml '
        '--speed $(arg speed) --wait-robots 60 $(arg sim_args)"/>']
    for rid in params.robots:
        lines += [
            f'  <include file="$(find {arch_pkg})/launch/{arch_pkg}.launch">',
            f'    <arg name="robot_id" value="{rid}"/>',
            f'    <arg name="robot_params" value="$(find {package})/config/{rid}_{stem}_params.yaml"/>',
            f'    <arg name="tasks_params" value="$(find {package})/config/tasks_{stem}_params.yaml"/>',
            f'    <arg name="layers_params" value="$(find {package})/config/layers_{stem}_params.yaml"/>',
            '    <arg name="agent_args" value="--sim-time"/>',
            "  </include>"]
    if dispatcher:
        lines += [
            "  <!-- the dispatcher: a lockstep participant beside the robots, planning on the "
            "instance -->",
            f'  <include file="$(find {arch_pkg})/launch/dispatcher.launch">',
            f'    <arg name="params" value="$(find {package})/config/dispatcher_{stem}_params.yaml"/>',
            f'    <arg name="instance" value="$(find {package})/config/instance.yaml"/>',
            '    <arg name="dispatcher_args" value="--application delivery --sim-time"/>',
            "  </include>"]
    lines.append("</launch>")
    return ("\n".join(lines) + "\n").encode()


def package_files(params: InstanceBody, answers: Answers, registry: Registry | None = None
                  ) -> dict[str, bytes]:
    """Every generated file of one package (relative path → bytes)."""
    reg = registry or Registry()
    arch_pkg, arch = reg.architecture(answers.architecture)
    stem = answers.architecture
    # the architecture's layers template (ALLIANCE's carries the patrol layers' sections) is
    # not this application's: its layers file names the instance, written below
    arch = dataclasses.replace(arch, configs=[c for c in arch.configs
                                              if c.id != f"layers_{stem}_params"])
    _, files = build_application(arch_pkg, arch, answers)
    files[f"config/layers_{stem}_params.yaml"] = layers_yaml(stem)
    planned = bool(arch.config(f"dispatcher_{stem}_params"))  # an architecture with a dispatcher
    files["launch/delivery_sim.launch"] = sim_launch(params, answers.package, arch_pkg.name, stem,
                                                     dispatcher=planned)
    files["config/instance.yaml"] = instance_yaml(params)
    return files


def instance_yaml(params: InstanceBody) -> bytes:
    """The instance as a document: the package's one copy, which its layers file, its robot
    files (SSI, CBBA) and its dispatcher (central) name."""
    head = ("# The delivery instance this package runs: its one copy, named by the layers file "
            "(and the\n# robot files or the dispatcher that plan on it). Written by `python -m "
            "mrta_delivery.generate_cli`\n# from delivery's config/instance.yaml; "
            "docs/delivery.md.\n")
    body = {"application": "delivery", **document_data(params)}
    return (head + document_yaml(body)).encode()


def all_files(params: InstanceBody, alliance: str = "delivery",
              murdoch: str = "delivery_murdoch",
              central: str = "delivery_central", ssi: str = "delivery_ssi",
              cbba: str = "delivery_cbba", tessi: str = "delivery_tessi") -> dict[str, bytes]:
    """Every package's generated files, by path under their common parent folder, and
    central's, SSI's and CBBA's answers files beside them."""
    files = {}
    made = ((alliance_answers(params, alliance), alliance),
            (murdoch_answers(params, murdoch), murdoch),
            (central_answers(params, central), central),
            (own_route_answers(params, "ssi", ssi), ssi),
            (own_route_answers(params, "cbba", cbba), cbba),
            (own_route_answers(params, "tessi", tessi), tessi))
    for answers, folder in made:
        files.update(_package(params, answers, folder))
    files[f"{alliance}/worlds/delivery.yaml"] = world_yaml(params)
    for answers, folder in made[2:]:
        files[f"{folder}_answers.yaml"] = answers_yaml(answers)
    return files


def _package(params: InstanceBody, answers: Answers, folder: str) -> dict[str, bytes]:
    return {f"{folder}/{rel}": data for rel, data in package_files(params, answers).items()}


def run_files(params: InstanceBody, architecture: str) -> dict[str, bytes]:
    """The packages one run under `architecture` reads: the application's own (`delivery`,
    ALLIANCE's, with the world) and, for another architecture, its package — not every
    architecture's and no answers files. At 100 robots × 100 tasks the six packages are ≈ 95 MB
    of YAML and XML (each robot file lists the tasks it can serve), ≈ 40 CPU-s to write; a
    CBBA run needs two of them (benchmarks/README.md, agent hosts)."""
    files = _package(params, alliance_answers(params), "delivery")
    files["delivery/worlds/delivery.yaml"] = world_yaml(params)
    if architecture == "alliance":
        return files
    if architecture == "murdoch":
        answers = murdoch_answers(params)
    elif architecture == "central":
        answers = central_answers(params)
    elif architecture in OWN_ROUTE:
        answers = own_route_answers(params, architecture, f"delivery_{architecture}")
    else:
        raise ConfigError(f"delivery derives no package for architecture {architecture!r} "
                          f"(it has alliance, murdoch, central, {', '.join(OWN_ROUTE)})")
    return {**files, **_package(params, answers, answers.package)}


def generate(params: InstanceBody, folder: Path, name: str = "delivery") -> list[Path]:
    """Write every package's generated files into `folder`: NAME (ALLIANCE), NAME_murdoch,
    NAME_central and NAME_central_answers.yaml. Everything is built before the first file is
    written, so a bad instance writes nothing; each file is replaced atomically (the package
    folders also hold this application's Python modules, so they are not replaced whole)."""
    files = all_files(params, name, f"{name}_murdoch", f"{name}_central", f"{name}_ssi",
                      f"{name}_cbba", f"{name}_tessi")
    written = []
    for rel, data in sorted(files.items()):
        path = folder / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        write_text(path, data.decode())
        written.append(path)
    return written


def derive(doc: InstanceDoc, folder: Path, architecture: str | None = None) -> list[Path]:
    """A run's own packages from an instance (`mrta demo --instance FILE`) in `folder`,
    replacing it whole or not at all: every package, or (`architecture`) those a run under it
    reads (run_files). Put first on the package path, they shadow the installed ones for that
    run; nothing is written into those."""
    body = doc.body()
    return write_folder(folder, all_files(body) if architecture is None
                        else run_files(body, architecture))
