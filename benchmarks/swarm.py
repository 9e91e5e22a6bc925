"""Swarm benchmark: N agents plus the simulator in lockstep on one machine.

A patrol-like application with N robots (the patrol tasks wander / border protection / report,
each robot given the parameters of patrol's robot ((k - 1) mod 3) + 1) is generated into a
temporary folder through the toolchain (`build_application`, what `mrta app new` runs), with a
hall large enough for N starts; then it runs the way `patrol_sim.launch` runs it: `mrta sim
--lockstep --speed 0 --wait-robots` and one `mrta agent … --sim-time` per robot, each a child
process ended by its PID.

Prints one JSON line per figure:
  swarm_run           real-time factor over the run once every agent is in step (the
                      simulator's clock starts only then; start-up time apart), ms per physics
                      step, per-agent CPU share over that window and RSS at its end, the
                      simulator's CPU share — for the baseline agent count and for N
  swarm_sim_alone     the same world and robots, no agent, no lockstep: the simulator's own
                      ms per step (what the agents and the barrier add is the difference)
  swarm_summary       N against the baseline: the lockstep + agents' share of a step, the
                      target (≥ 1× real time with N = 100)

Each line carries the machine's load average when it was measured (others may share it).

Run: python benchmarks/swarm.py [--robots 100] [--baseline-robots 10] [--seconds 60]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import socket
import sys
import tempfile
import time
from pathlib import Path

HERE = os.path.abspath(__file__)
sys.path.insert(0, os.path.dirname(HERE))  # also when loaded by path (tests/test_swarm_lockstep.py)
from procstat import private_mb, proc_stat  # noqa: E402  (benchmarks/procstat.py, beside this)

sys.path[:] = [p for p in sys.path if os.path.abspath(p or ".") != os.path.dirname(HERE)]

import yaml  # noqa: E402

from mrta_zenoh.architectures import TEAM_ENV  # noqa: E402
from mrta_zenoh.bus.options import private_rendezvous  # noqa: E402
from mrta_zenoh.processes import ProcessGroup, mrta_argv  # noqa: E402

ROOT = Path(HERE).parent.parent
ANSWERS = ROOT / "configs" / "applications" / "patrol_answers.yaml"
STEP = 0.02          # the simulator's physics step (simulated seconds)
SPACING = 2.5        # metres between two robots' starts
COLUMNS = 16         # starts per row: the hall stays 40 m long, as patrol's
START_TIMEOUT = 300  # wall seconds for every agent to join (100 interpreters on 2 cores)
TASKS = ("wander", "border_protection", "report")


def hall(n: int) -> tuple[float, float]:
    """Half-length and half-width of a hall holding n starts on a grid (patrol's 40 × 12 m at
    least)."""
    rows = math.ceil(n / COLUMNS)
    return 20.0, max(6.0, rows * SPACING / 2 + 1.5)


def world_yaml(n: int) -> str:
    """Patrol's hall, widened for n robots, with its shelf and crates moved to the far end."""
    hx, hy = hall(n)
    starts = {}
    for k in range(n):
        row, col = divmod(k, COLUMNS)
        starts[f"robot{k + 1}"] = [round(-hx + SPACING / 2 + col * SPACING, 2),
                                   round(-hy + 1.5 + row * SPACING, 2), 0]
    doc = {"name": f"swarm{n}",
           "walls": [{"polygon": [[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]]}],
           "robots": starts, "border": [[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]]}
    return yaml.safe_dump(doc, sort_keys=False, default_flow_style=None)


def generate(n: int, folder: Path, tasks: tuple[str, ...] = TASKS
             ) -> tuple[Path, Path, list[str]]:
    """The N-robot application package with patrol's `tasks` (all three, or some of them),
    written into `folder` through the toolchain; returns its config folder, its world file and
    its robots."""
    from mrta_zenoh.toolchain.generator import Answers, build_application
    from mrta_zenoh.toolchain.registry import Registry

    base = yaml.safe_load(ANSWERS.read_text())
    per_robot = base["configs"]["alliance_params"]
    keep = [i for i, t in enumerate(base["robots"]["robot1"]) if t in tasks]
    if len(keep) != len(tasks):
        raise ValueError(f"tasks {tasks}: patrol's are {base['robots']['robot1']}")
    robots = [f"robot{k + 1}" for k in range(n)]
    hx, hy = hall(n)
    configs = dict(base["configs"])
    configs["alliance_params"] = {}
    for k, r in enumerate(robots):
        params = dict(per_robot[f"robot{k % 3 + 1}"], name=f"Robot {k + 1}")
        params["behaviour_sets"] = [params["behaviour_sets"][i] for i in keep]
        configs["alliance_params"][r] = params
    configs["tasks_alliance_params"] = {"tasks": [
        base["configs"]["tasks_alliance_params"]["tasks"][i] for i in keep]}
    configs["layers_alliance_params"] = dict(
        base["configs"]["layers_alliance_params"],
        BorderProtection={"x_min": -hx, "y_min": -hy, "x_max": hx, "y_max": hy})
    answers = Answers(package=f"swarm{n}_{len(tasks)}", name=f"Swarm of {n}",
                      architecture="alliance",
                      robots={r: list(tasks) for r in robots}, configs=configs,
                      description=f"{n} robots patrol a hall with ALLIANCE (benchmarks/swarm.py)",
                      depends=["simulator", "patrol"], maintainer=base["maintainer"],
                      email=base["email"], license=base["license"], version=base["version"])
    arch_pkg, arch = Registry().architecture("alliance")
    _, files = build_application(arch_pkg, arch, answers)
    pkg = folder / answers.package
    for rel, data in files.items():
        (pkg / rel).parent.mkdir(parents=True, exist_ok=True)
        (pkg / rel).write_bytes(data)
    world = pkg / "worlds" / f"swarm{n}.yaml"
    world.parent.mkdir(parents=True, exist_ok=True)
    world.write_text(world_yaml(n))
    return pkg / "config", world, robots


def load() -> list[float]:
    return [round(x, 2) for x in os.getloadavg()]


def client(topology: str, env: dict) -> list[str]:
    """Bus options of every process: the default peer mesh, or a client of the run's router."""
    if topology == "peer":
        return []
    return ["--mode", "client", "--connect", env["MRTA_RENDEZVOUS"]]


def start_router(group: ProcessGroup, topology: str, env: dict):
    """`mrta router` on the rendezvous (topology "router"), up once its port accepts: every
    other process is its client."""
    if topology != "router":
        return None
    router = group.start(mrta_argv("router"), name="router")
    host, port = env["MRTA_RENDEZVOUS"].split("/", 1)[1].rsplit(":", 1)
    deadline = time.monotonic() + 60
    while True:
        try:
            socket.create_connection((host, int(port)), timeout=1).close()
            return router
        except OSError:
            if not router.running() or time.monotonic() > deadline:
                raise RuntimeError(f"the router did not come up:\n{router.tail()}") from None
            time.sleep(0.1)


def sim_argv(world: Path, robots: list[str], seconds: float, lockstep: bool,
             bus: list[str]) -> list[str]:
    args = ["sim", "--world", world, "--speed", "0", "--duration", seconds, *bus]
    for r in robots:
        args += ["--robot", r]
    if lockstep:
        args += ["--lockstep", "--wait-robots", START_TIMEOUT]
    return mrta_argv(*args)


def parse_done(line: str) -> tuple[float, float]:
    """(simulated, wall) seconds from the simulator's `done:` line."""
    words = line.split("done: ", 1)[1].split()
    return float(words[0]), float(words[4])


def swarm(n: int, seconds: float, env: dict, folder: Path, topology: str,
          tasks: tuple[str, ...] = TASKS) -> dict:
    """N agents and the simulator in lockstep: the run's figures."""
    config, world, robots = generate(n, folder, tasks)
    env = dict(env, **{TEAM_ENV: ",".join(robots)})
    t0 = time.monotonic()
    bus = client(topology, env)
    with ProcessGroup(env) as group:
        router = start_router(group, topology, env)
        agents = [group.start(mrta_argv(
            "-q", "agent", r, *bus, "--robot-params", config / f"{r}_alliance_params.yaml",
            "--tasks-params", config / "tasks_alliance_params.yaml",
            "--layers-params", config / "layers_alliance_params.yaml", "--sim-time",
            "--seed", "0"), name=r) for r in robots]
        sim = group.start(sim_argv(world, robots, seconds, True, bus), name="sim")
        ready = sim.wait_stderr(lambda line: "ready:" in line, START_TIMEOUT + 60)
        startup = time.monotonic() - t0
        if f"lockstep with {n} participants" not in ready:
            raise RuntimeError(f"not every agent joined: {ready}")
        hub = [router] if router is not None else []
        gone = [c for c in agents + [sim] + hub if not c.running()]
        if gone:
            raise RuntimeError(f"{gone[0].name} {gone[0].describe_exit()} before the run:\n"
                               + gone[0].tail())
        before = {c.pid: proc_stat(c.pid) for c in agents + [sim] + hub}
        w0 = time.monotonic()
        done = sim.wait_stderr(lambda line: "done:" in line, 600)
        window = time.monotonic() - w0
        gone = [c for c in agents + hub if not c.running()]
        if gone:  # a process that died during the run makes its figures meaningless
            raise RuntimeError(f"{gone[0].name} {gone[0].describe_exit()} during the run:\n"
                               + gone[0].tail())
        after = {c.pid: proc_stat(c.pid) for c in agents + [sim] + hub}
        uss = [private_mb(c.pid) for c in agents]
        sim.wait(60)
        simulated, wall = parse_done(done)
        cpu = [(after[c.pid][0] - before[c.pid][0]) / window * 100 for c in agents]
        rss = [after[c.pid][1] / 2**20 for c in agents]
        sim_cpu = (after[sim.pid][0] - before[sim.pid][0]) / window * 100
        router_cpu = sum(after[c.pid][0] - before[c.pid][0] for c in hub) / window * 100
        failed = [c.name for c in group.failed()]
        if failed:
            raise RuntimeError(f"children failed: {', '.join(failed)}")
    return {"figure": "swarm_run", "robots": n, "agents": n, "lockstep": True,
            "topology": topology, "tasks": list(tasks),
            "startup_s": round(startup, 1), "simulated_s": simulated, "wall_s": wall,
            "real_time_factor": round(simulated / wall, 2),
            "ms_per_step": round(wall / (simulated / STEP) * 1e3, 3),
            "agent_cpu_percent_of_a_core_mean": round(sum(cpu) / n, 2),
            "agent_cpu_percent_of_a_core_max": round(max(cpu), 2),
            "agents_cpu_cores_total": round(sum(cpu) / 100, 2),
            "sim_cpu_percent_of_a_core": round(sim_cpu, 1),
            "router_cpu_percent_of_a_core": round(router_cpu, 1) if hub else None,
            "agent_rss_mb_mean": round(sum(rss) / n, 1), "agent_rss_mb_max": round(max(rss), 1),
            "agents_rss_gb_total": round(sum(rss) / 1024, 2),
            "agent_uss_mb_mean": round(sum(uss) / n, 1),
            "agents_uss_gb_total": round(sum(uss) / 1024, 2),
            "load_average": load(), "cpus": os.cpu_count()}


def sim_alone(n: int, seconds: float, env: dict, folder: Path, topology: str) -> dict:
    """The same world and robots without agents or lockstep: the simulator's own step."""
    _, world, robots = generate(n, folder)
    with ProcessGroup(env) as group:
        start_router(group, topology, env)
        sim = group.start(sim_argv(world, robots, seconds, False, client(topology, env)),
                          name="sim")
        done = sim.wait_stderr(lambda line: "done:" in line, 600)
        sim.wait(60)
    simulated, wall = parse_done(done)
    return {"figure": "swarm_sim_alone", "robots": n, "agents": 0, "lockstep": False,
            "simulated_s": simulated, "wall_s": wall,
            "real_time_factor": round(simulated / wall, 2),
            "ms_per_step": round(wall / (simulated / STEP) * 1e3, 3), "load_average": load()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robots", type=int, default=100)
    ap.add_argument("--baseline-robots", type=int, default=10,
                    help="the same run with this many agents (0: none)")
    ap.add_argument("--seconds", type=float, default=60.0, help="simulated seconds per run")
    ap.add_argument("--tasks", default=",".join(TASKS),
                    help="patrol's tasks the robots have (with report, every robot's "
                         "ledger hears every teammate's log once a second: N² small samples)")
    ap.add_argument("--topology", choices=("router", "peer"), default="router",
                    help="router: `mrta router` and every process its client (a star: N + 1 "
                         "links); peer: the default peer mesh (N(N + 1)/2 links)")
    args = ap.parse_args()
    tasks = tuple(args.tasks.split(","))
    env = dict(os.environ, MRTA_RENDEZVOUS=private_rendezvous(), RUST_LOG="error")
    with tempfile.TemporaryDirectory(prefix="mrta-swarm-") as tmp:
        folder = Path(tmp)
        alone = sim_alone(args.robots, args.seconds * 5, env, folder, args.topology)
        print(json.dumps(alone), flush=True)
        base = None
        if args.baseline_robots:
            base = swarm(args.baseline_robots, args.seconds, env, folder, args.topology, tasks)
            print(json.dumps(base), flush=True)
        run = swarm(args.robots, args.seconds, env, folder, args.topology, tasks)
        print(json.dumps(run), flush=True)
    print(json.dumps({
        "figure": "swarm_summary", "robots": args.robots,
        "real_time_factor": run["real_time_factor"],
        "baseline_real_time_factor": base and base["real_time_factor"],
        "baseline_robots": args.baseline_robots,
        "ms_per_step": run["ms_per_step"],
        "ms_per_step_sim_alone": alone["ms_per_step"],
        "lockstep_and_agents_ms_per_step": round(run["ms_per_step"] - alone["ms_per_step"], 3),
        "target_real_time_factor_min": 1.0, "load_average": load()}), flush=True)


if __name__ == "__main__":
    main()
