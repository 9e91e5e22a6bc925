"""Team sizes: delivery with N = 5, 10, 20, 50, 100 robots in lockstep on this machine, each beside
the simulator alone at the same N (issue 39 point 5).

For each N a delivery instance is generated (`mrta instance generate delivery`: N robots, N tasks,
a room grown with N so starts and tasks keep their spacing, seed 1) and its packages derived
(what `mrta demo --instance` derives into its output folder); then, each a child process ended by
its PID:

* `team_run` — the derived launch file (`delivery_sim.launch`: `mrta sim --lockstep --speed 0`
  and one ALLIANCE agent per robot on simulated time, all on one private rendezvous: a peer
  mesh, or with `--topology router` every process a client of `mrta router` on it, as `mrta
  demo` starts them from 20 robots up): start-up (the first process started → the simulator's `ready:`, every
  agent in step; and each agent's CPU seconds until then, which the machine's load does not
  change), the real-time factor once running (the simulator's `done:` line: simulated
  over wall seconds, start-up apart), agents' CPU share, RSS and private memory (USS) at the end;
* `team_sim_alone` — the same world and robots with no agent and no lockstep: what the physics
  alone costs at that N;
* with `--demo`, `team_demo` — the whole mission (`mrta demo --instance FILE`: recorder,
  supervisor, summary) at that N: whether it completes, its wall time and the summary's
  `lockstep_exact`.

One JSON line per figure on stdout, each with the load average when measured (others may share
the machine); `--plot FILE` draws the real-time factors and the agents' RSS against N.

Run: python benchmarks/team_sizes.py [--robots 5 10 20 50 100] [--seconds 30] [--demo]
                                     [--topology peer|router]
                                     [--plot benchmarks/img/team_sizes.png]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import tempfile
import time
from pathlib import Path

HERE = os.path.abspath(__file__)
sys.path.insert(0, os.path.dirname(HERE))
from procstat import private_mb, proc_stat  # noqa: E402  (benchmarks/procstat.py, beside this)
from swarm import client, start_router  # noqa: E402  (the router topology, as swarm.py runs it)

sys.path[:] = [p for p in sys.path if os.path.abspath(p or ".") != os.path.dirname(HERE)]

from mrta_zenoh.bus.options import private_rendezvous  # noqa: E402
from mrta_zenoh.processes import ProcessGroup, mrta_argv  # noqa: E402

STEP = 0.02             # the simulator's physics step (simulated seconds)
START_TIMEOUT = 300     # wall seconds for every agent to join
SEED = 1


def room(n: int) -> tuple[float, float]:
    """The room for n robots and n tasks: the default 12 × 8 m up to 5, then grown so the area
    per robot and task stays that of 5 robots and 5 tasks (≈ 9.6 m² each)."""
    w = max(12.0, 12.0 * math.sqrt(n / 5))
    return round(w, 1), round(w * 2 / 3, 1)


def instance(n: int, folder: Path) -> Path:
    from mrta_zenoh.instances import generate

    path = folder / f"delivery-r{n}-t{n}-{SEED}.yaml"
    generate("delivery", {"robots": n, "tasks": n, "room": list(room(n))}, SEED, path)
    return path


def derived(path: Path, folder: Path) -> Path:
    """The instance's packages (delivery, delivery_murdoch), as `mrta demo --instance` derives
    them; returns the folder to put first on the package path."""
    from mrta_delivery.generate import derive
    from mrta_delivery.instance import load_document

    out = folder / f"pkgs-{path.stem}"
    derive(load_document(path), out)
    return out


def load() -> list[float]:
    return [round(x, 2) for x in os.getloadavg()]


def parse_done(line: str) -> tuple[float, float]:
    """(simulated, wall) seconds from the simulator's `done:` line."""
    words = line.split("done: ", 1)[1].split()
    return float(words[0]), float(words[4])


def nodes_of(pkgs: Path, seconds: float, lockstep: bool, bus: list[str] = ()):
    """The launch file's nodes, each given `bus` (the topology's bus options) besides."""
    from mrta_zenoh.toolchain.launchfile import LaunchEvaluator
    from mrta_zenoh.toolchain.registry import Registry

    reg = Registry([pkgs])
    sim_args = f"--duration {seconds}" + (" --lockstep" if lockstep else "")
    nodes = LaunchEvaluator(lambda name: reg.find(name).path).run(
        pkgs / "delivery" / "launch" / "delivery_sim.launch",
        {"speed": "0", "seed": "0", "sim_args": sim_args})
    for node in nodes:
        node.args += list(bus)
    return nodes


def team_run(n: int, pkgs: Path, seconds: float, env: dict, topology: str) -> dict:
    from mrta_zenoh.toolchain.runner import start_nodes

    nodes = nodes_of(pkgs, seconds, lockstep=True, bus=client(topology, env))
    t0 = time.monotonic()
    with ProcessGroup(env) as group:
        router = start_router(group, topology, env)
        children = start_nodes(group, nodes)
        sim = next(c for c in children if c.name == "sim")
        agents = [c for c in children if c is not sim]
        ready = sim.wait_stderr(lambda line: "ready:" in line, START_TIMEOUT + 60)
        startup = time.monotonic() - t0
        if f"lockstep with {n} participants" not in ready:
            raise RuntimeError(f"not every agent joined: {ready}")
        hub = [router] if router is not None else []
        before = {c.pid: proc_stat(c.pid) for c in children + hub}
        w0 = time.monotonic()
        done = sim.wait_stderr(lambda line: "done:" in line, 3600)
        window = time.monotonic() - w0
        gone = [c for c in agents if not c.running()]
        if gone:
            raise RuntimeError(f"{gone[0].name} {gone[0].describe_exit()} during the run:\n"
                               + gone[0].tail())
        after = {c.pid: proc_stat(c.pid) for c in children + hub}
        uss = [private_mb(c.pid) for c in agents]
        sim.wait(60)
    simulated, wall = parse_done(done)
    used = [after[c.pid][0] - before[c.pid][0] for c in agents]
    cpu = [u / window * 100 for u in used]
    rss = [after[c.pid][1] / 2**20 for c in agents]
    return {"figure": "team_run", "robots": n, "tasks": n, "room": list(room(n)),
            "topology": topology, "lockstep": True, "startup_s": round(startup, 1),
            "simulated_s": simulated,
            "wall_s": wall, "real_time_factor": round(simulated / wall, 2),
            "ms_per_step": round(wall / (simulated / STEP) * 1e3, 3),
            "agent_cpu_percent_of_a_core_mean": round(sum(cpu) / n, 2),
            "agents_cpu_cores_total": round(sum(cpu) / 100, 2),
            # what the machine's load does not change: CPU the agents spent per simulated second
            "agents_cpu_s_per_simulated_s": round(sum(used) / simulated, 3),
            "router_cpu_percent_of_a_core": round(sum(
                after[c.pid][0] - before[c.pid][0] for c in hub) / window * 100, 1)
            if hub else None,
            "sim_cpu_percent_of_a_core": round(
                (after[sim.pid][0] - before[sim.pid][0]) / window * 100, 1),
            "agent_startup_cpu_s_mean": round(sum(before[c.pid][0] for c in agents) / n, 2),
            "agent_rss_mb_mean": round(sum(rss) / n, 1), "agent_rss_mb_max": round(max(rss), 1),
            "agent_uss_mb_mean": round(sum(uss) / n, 1),
            "agents_uss_gb_total": round(sum(uss) / 1024, 2),
            "load_average": load(), "cpus": os.cpu_count()}


def sim_alone(n: int, pkgs: Path, seconds: float, env: dict) -> dict:
    from mrta_zenoh.toolchain.runner import command_for, env_for

    sim = next(x for x in nodes_of(pkgs, seconds, lockstep=False) if x.name == "sim")
    argv = [a for a in command_for(sim)]
    wait = argv.index("--wait-robots")  # no agent will come: do not wait for any
    del argv[wait:wait + 2]
    with ProcessGroup(env) as group:
        child = group.start(argv, name="sim", env=env_for(sim))
        done = child.wait_stderr(lambda line: "done:" in line, 3600)
        child.wait(60)
    simulated, wall = parse_done(done)
    return {"figure": "team_sim_alone", "robots": n, "lockstep": False, "simulated_s": simulated,
            "wall_s": wall, "real_time_factor": round(simulated / wall, 2),
            "ms_per_step": round(wall / (simulated / STEP) * 1e3, 3), "load_average": load()}


def demo(n: int, path: Path, seconds: float, folder: Path, env: dict) -> dict:
    out = folder / f"demo-{n}"
    t0 = time.monotonic()
    with ProcessGroup(env) as group:
        child = group.start(mrta_argv("-q", "demo", "--application", "delivery", "--instance",
                                      path, "--duration", seconds, "--speed", "0", "--no-live",
                                      "--no-plots", "--fail", "none", "--output", out),
                            name="demo", merge_stderr=True)
        rc = child.wait(3600)
        tail = child.tail(20)
    wall = time.monotonic() - t0
    summary = json.loads((out / "summary.json").read_text()) if rc == 0 else {}
    return {"figure": "team_demo", "robots": n, "exit": rc, "wall_s": round(wall, 1),
            "summary_wall_s": summary.get("wall_seconds"),
            "lockstep_exact": summary.get("lockstep_exact"),
            "run_status": summary.get("run_status"),
            "completed": summary.get("metrics", {}).get("completed"),
            **({} if rc == 0 else {"tail": tail[-600:]}), "load_average": load()}


def plot(lines: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    runs = sorted((d for d in lines if d["figure"] == "team_run"), key=lambda d: d["robots"])
    alone = sorted((d for d in lines if d["figure"] == "team_sim_alone"),
                   key=lambda d: d["robots"])
    fig, (left, right) = plt.subplots(1, 2, figsize=(10, 4), dpi=100)
    left.plot([d["robots"] for d in runs], [d["real_time_factor"] for d in runs], "o-",
              label="agents + simulator, lockstep"
              + (f" ({runs[0]['topology']})" if runs and "topology" in runs[0] else ""))
    left.plot([d["robots"] for d in alone], [d["real_time_factor"] for d in alone], "s--",
              label="simulator alone")
    left.axhline(1.0, color="grey", linewidth=0.8)
    left.set(xscale="log", yscale="log", xlabel="robots (= tasks)",
             ylabel="real-time factor (simulated / wall s)", title="delivery, speed 0")
    left.legend(fontsize=8)
    right.plot([d["robots"] for d in runs], [d["agent_rss_mb_mean"] for d in runs], "o-",
               label="RSS")
    right.plot([d["robots"] for d in runs], [d["agent_uss_mb_mean"] for d in runs], "s-",
               label="private (USS)")
    right.axhline(45.0, color="grey", linewidth=0.8, linestyle=":", label="45 MB target at 50")
    right.set(xscale="log", xlabel="robots", ylabel="MB per agent", title="agent memory")
    right.legend(fontsize=8)
    ns = sorted({d["robots"] for d in runs + alone})
    for ax in (left, right):
        ax.set_xticks(ns, [str(n) for n in ns])
        ax.minorticks_off()
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robots", type=int, nargs="+", default=[5, 10, 20, 50, 100])
    ap.add_argument("--seconds", type=float, default=30.0, help="simulated seconds per run")
    ap.add_argument("--topology", choices=("peer", "router"), default="peer",
                    help="peer: the launch's peer mesh (as `mrta demo` runs it); router: `mrta "
                         "router` and every process its client (as swarm.py runs patrol)")
    ap.add_argument("--demo", action="store_true", help="also the whole mission at each N")
    ap.add_argument("--plot", type=Path, help="draw the figures into this PNG")
    args = ap.parse_args()
    lines = []
    with tempfile.TemporaryDirectory(prefix="mrta-teams-") as tmp:
        folder = Path(tmp)
        for n in args.robots:
            path = instance(n, folder)
            pkgs = derived(path, folder)
            env = dict(os.environ, MRTA_RENDEZVOUS=private_rendezvous(), RUST_LOG="error",
                       MRTA_PACKAGE_PATH=str(pkgs))
            for figure in (lambda: sim_alone(n, pkgs, args.seconds * 5, env),
                           lambda: team_run(n, pkgs, args.seconds, env, args.topology)):
                lines.append(figure())
                print(json.dumps(lines[-1]), flush=True)
            if args.demo:
                env = dict(os.environ, RUST_LOG="error")
                lines.append(demo(n, path, args.seconds, folder, env))
                print(json.dumps(lines[-1]), flush=True)
    if args.plot:
        plot(lines, args.plot)


if __name__ == "__main__":
    main()
