"""Agent hosts (issue 47): what a run costs with one process per robot and with the team in hosts.

Each figure is a whole mission (`mrta demo --instance FILE --speed 0 --no-plots`: simulator,
agents, recorder, supervisor, summary), a child process ended by its PID; its CPU is read from
/proc every 0.2 s for the demo and every process under it, by role (the agents — robots'
processes or hosts —, the simulator, the recorder, the runner with its supervisor and
analysis), its wall time the command's. Printed, one JSON line per figure:

* `run_cost` — a 5-robot × 10-task delivery run (seed 1 instance) with `--agents-per-process 1`
  (the baseline, same run) and with one host for the team: CPU-s, wall s, and whether the two
  summaries agree but for the machine's fields;
* `team_size` — with `--sizes`: N robots and N tasks (room grown with N) under each of
  `--architectures` with the team in hosts of `--per-host` robots (default: all in one), the
  whole mission: wall time, the real-time factor (simulated over wall seconds, start-up
  included), CPU-s, and the summary's `run_status` and `lockstep_exact`.

* `own_delivery` — with `--hear-sizes`: one bus (real Zenoh session) with K subscriptions to
  every robot's CBBA `Bids`, as K robots in one host hold, and a 100-winner `Bids` published on
  it: CPU µs per publish decoded once for the K (the bus now) against once per subscription
  (the baseline, the same bus and subscriptions: what `_hand_over` did before);
* `remote_delivery` — with `--hear-sizes`: the same K subscriptions, the `Bids` published by
  another session: this process's CPU µs per sample with one native Zenoh subscriber fanned out
  to the K (the bus now) against one native subscriber per subscription (the baseline, same
  run).

* `startup` — with `--startup-sizes`: N robots and N tasks, one process per robot (the
  baseline) and the team in one host, a short run each (`--startup-duration`): wall s from the
  command to every robot's agent up (the runner's `agents up` line) and the agents' resident
  memory per robot then.

Each line carries the load average when it was measured (others may share the machine).

Run: python benchmarks/hosts.py [--repeat 2] [--sizes 5 10 20 50 100] [--architectures cbba
                                alliance] [--per-host 0] [--duration 20]
                                [--startup-sizes 5 10 20 50 100] [--hear-sizes 10 100]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

from mrta_supervisor.mission.compare import run_differences
from mrta_supervisor.mission.runner import AGENTS_UP

TICK = os.sysconf("SC_CLK_TCK")
PAGE_KB = os.sysconf("SC_PAGE_SIZE") // 1024
ROLES = (("agents", ("/agent ", "/host ")), ("simulator", ("simulator/sim",)),
         ("recorder", (" view ", " record ")), ("router", (" router",)))


def role(cmdline: str) -> str:
    return next((name for name, marks in ROLES if any(m in cmdline for m in marks)), "runner")


def tree(root: int) -> list[int]:
    kids: dict[int, list[int]] = {}
    for d in os.listdir("/proc"):
        if d.isdigit():
            try:
                with open(f"/proc/{d}/stat") as f:
                    kids.setdefault(int(f.read().rsplit(")", 1)[1].split()[1]), []).append(int(d))
            except OSError:
                continue
    out, stack = [], [root]
    while stack:
        pid = stack.pop()
        out.append(pid)
        stack.extend(kids.get(pid, []))
    return out


def sample(root: int, seen: dict[int, tuple[float, str]]) -> dict[str, int]:
    """Each process's CPU seconds so far and its role (first seen), under `root`; returns the
    resident memory (kB) of each role's processes now."""
    rss: dict[str, int] = {}
    for pid in tree(root):
        try:
            with open(f"/proc/{pid}/stat") as f:
                fields = f.read().rsplit(")", 1)[1].split()
            cpu = (int(fields[11]) + int(fields[12])) / TICK
            name = seen[pid][1] if pid in seen else role(
                open(f"/proc/{pid}/cmdline").read().replace("\0", " "))
            kb = int(fields[21]) * PAGE_KB
        except (OSError, IndexError):
            continue
        seen[pid] = (cpu, name)
        rss[name] = rss.get(name, 0) + kb
    return rss


def mrta(*args: str) -> list[str]:
    return [sys.executable, "-m", "mrta_zenoh.cli.main", *args]


def instance(folder: Path, robots: int, tasks: int) -> Path:
    """A delivery instance of `robots` and `tasks`, its room grown with the team."""
    side = max(1.0, (max(robots, tasks) / 5) ** 0.5)
    path = folder / f"i{robots}x{tasks}.yaml"
    subprocess.run(mrta("instance", "generate", "delivery", "--robots", str(robots), "--tasks",
                        str(tasks), "--room", f"{12 * side:.1f}", f"{8 * side:.1f}", "--seed",
                        "1", "-o", str(path)), check=True, capture_output=True)
    return path


def demo(inst: Path, out: Path, arch: str, per_process: int, duration: float) -> dict:
    """One whole mission; its wall, CPU, summary, start-up (wall s from the command to the
    runner's `agents up` line: every robot's agent token seen) and the agents' resident memory
    then (kB, all their processes together)."""
    t0, seen, lines = time.monotonic(), {}, []
    proc = subprocess.Popen(mrta("demo", "--application", "delivery", "--instance", str(inst),
                                 "--architecture", arch,
                                 "--fail", "none", "--duration", str(duration), "--speed", "0",
                                 "--no-plots", "--no-live", "--seed", "1",
                                 "--agents-per-process", str(per_process), "--output", str(out)),
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    reader = threading.Thread(target=lambda: lines.extend(
        (time.monotonic() - t0, line) for line in proc.stderr), daemon=True)
    reader.start()
    up = rss_up = None
    try:
        while proc.poll() is None:
            rss = sample(proc.pid, seen)
            if up is None and any(AGENTS_UP in line for _, line in list(lines)):
                up = next(t for t, line in list(lines) if AGENTS_UP in line)
                rss_up = rss.get("agents")
            time.sleep(0.2)
        reader.join(5)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    wall = time.monotonic() - t0
    by_role: dict[str, float] = {}
    for c, name in seen.values():
        by_role[name] = round(by_role.get(name, 0.0) + c, 2)
    cpu = round(sum(by_role.values()), 2)
    summary = json.loads((out / "summary.json").read_text()) if proc.returncode == 0 else {}
    return {"rc": proc.returncode, "wall_s": round(wall, 2), "cpu_s": cpu, "cpu_by_role": by_role,
            "summary": summary, "startup_s": None if up is None else round(up, 2),
            "agents_rss_kb": rss_up,
            "error": [line.strip() for _, line in lines][-1:] if proc.returncode else []}


def emit(**figure) -> None:
    figure["load"] = round(os.getloadavg()[0], 1)
    print(json.dumps(figure), flush=True)


def run_cost(folder: Path, repeat: int, duration: float, arch: str) -> None:
    inst = instance(folder, 5, 10)
    for i in range(repeat):
        one = demo(inst, folder / f"k1-{i}", arch, 1, duration)
        host = demo(inst, folder / f"k5-{i}", arch, 5, duration)
        emit(figure="run_cost", architecture=arch, robots=5, tasks=10, duration=duration,
             per_process_cpu_s=one["cpu_s"], per_process_wall_s=one["wall_s"],
             hosted_cpu_s=host["cpu_s"], hosted_wall_s=host["wall_s"],
             cpu_ratio=round(one["cpu_s"] / host["cpu_s"], 2) if host["cpu_s"] else None,
             per_process_by_role=one["cpu_by_role"], hosted_by_role=host["cpu_by_role"],
             agents_cpu_ratio=round(one["cpu_by_role"].get("agents", 0)
                                    / host["cpu_by_role"]["agents"], 2)
             if host["cpu_by_role"].get("agents") else None,
             identical=bool(one["summary"]) and bool(host["summary"])
             and not run_differences(one["summary"], host["summary"]),
             rc=[one["rc"], host["rc"]], error=one["error"] + host["error"])


def team_size(folder: Path, sizes: list[int], archs: list[str], per_host: int,
              duration: float) -> None:
    for n in sizes:
        inst = instance(folder, n, n)
        for arch in archs:
            k = per_host or n
            r = demo(inst, folder / f"n{n}-{arch}", arch, k, duration)
            s = r["summary"]
            emit(figure="team_size", architecture=arch, robots=n, tasks=n, per_host=k,
                 duration=duration, wall_s=r["wall_s"], cpu_s=r["cpu_s"],
                 cpu_by_role=r["cpu_by_role"],
                 real_time_factor=round(duration / r["wall_s"], 3), startup_s=r["startup_s"],
                 agents_rss_mb=None if r["agents_rss_kb"] is None
                 else round(r["agents_rss_kb"] / 1024, 1),
                 run_status=s.get("run_status"), lockstep_exact=s.get("lockstep_exact"),
                 completed=s.get("metrics", {}).get("completed"), rc=r["rc"], error=r["error"])


def own_delivery(sizes: list[int], publishes: int = 300) -> None:
    from mrta_agent.cbba.messages import Bids
    from mrta_zenoh import codec
    from mrta_zenoh.bus import BusOptions
    from mrta_zenoh.bus.zenoh_bus import ZenohBus
    from mrta_zenoh.messages import Header

    msg = Bids(Header("robot1", 1.0, 1), tuple((t, t % 100, 10.0 + t) for t in range(100)),
               tuple((r, 1.0) for r in range(100)), (), 0.0, 0.0, instance="0" * 16)
    key, enc = "cbba/robot1/bids", codec.encoding_for(Bids.TYPE_NAME)
    for k in sizes:
        with ZenohBus(BusOptions(listen=["tcp/127.0.0.1:0"])) as bus:
            heard = []
            for _ in range(k):
                bus.subscribe("cbba/*/bids", heard.append, msg_type=Bids)
            subs = bus._own_subscriptions(key)

            def per_subscription(payload: bytes) -> None:
                for sub in subs:
                    sub._dispatch(key, enc, payload)

            def once(payload: bytes) -> None:
                bus._hand_over(subs, key, enc, payload)

            figures = {}
            for name, hand_over in (("per_subscription", per_subscription), ("once", once)):
                payload = codec.encode_struct(msg)
                t0 = time.process_time()
                for _ in range(publishes):
                    hand_over(payload)
                figures[name] = (time.process_time() - t0) / publishes * 1e6
                heard.clear()
        emit(figure="own_delivery", subscriptions=k, winners=100, publishes=publishes,
             per_subscription_us=round(figures["per_subscription"], 1),
             once_us=round(figures["once"], 1),
             ratio=round(figures["per_subscription"] / figures["once"], 2))


def remote_delivery(sizes: list[int], publishes: int = 300) -> None:
    """Two buses (real Zenoh sessions on loopback), K subscriptions to every robot's `Bids` on
    one, 100-winner `Bids` published on the other: this process's CPU µs per published sample
    with one native subscriber for the K (the bus now) against one native subscriber per
    subscription (the baseline, the same subscriptions: what `ZenohBus._declare` did before)."""
    import socket

    from mrta_agent.cbba.messages import Bids
    from mrta_zenoh.bus import BusOptions
    from mrta_zenoh.bus.zenoh_bus import ZenohBus
    from mrta_zenoh.messages import Header

    msg = Bids(Header("robot1", 1.0, 1), tuple((t, t % 100, 10.0 + t) for t in range(100)),
               tuple((r, 1.0) for r in range(100)), (), 0.0, 0.0, instance="0" * 16)
    expr = "cbba/*/bids"
    for k in sizes:
        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            port = s.getsockname()[1]
        with ZenohBus(BusOptions(listen=[f"tcp/127.0.0.1:{port}"])) as here, \
                ZenohBus(BusOptions(connect=[f"tcp/127.0.0.1:{port}"],
                                    listen=["tcp/127.0.0.1:0"])) as there:
            heard: list = []
            subs = [here.subscribe(expr, heard.append, msg_type=Bids) for _ in range(k)]
            fan = here._fans[expr]

            def measure() -> float:
                while not heard:  # until the native subscribers are matched
                    there.publish("cbba/robot1/bids", msg)
                    time.sleep(0.05)
                time.sleep(0.3)
                heard.clear()
                t0 = time.process_time()
                for _ in range(publishes):
                    there.publish("cbba/robot1/bids", msg)
                deadline = time.monotonic() + 120
                while len(heard) < k * publishes and time.monotonic() < deadline:
                    time.sleep(0.01)
                spent = time.process_time() - t0
                heard.clear()
                return spent / publishes * 1e6

            fan.native.undeclare()
            natives = [here.session.declare_subscriber(here._wire(expr), here._receiver(sub, 0))
                       for sub in subs]
            per_native = measure()
            for native in natives:
                native.undeclare()
            fan.native = here.session.declare_subscriber(here._wire(expr), fan.on_sample)
            once = measure()
        emit(figure="remote_delivery", subscriptions=k, winners=100, publishes=publishes,
             per_native_subscriber_us=round(per_native, 1), one_native_us=round(once, 1),
             ratio=round(per_native / once, 2))


def startup(folder: Path, sizes: list[int], arch: str, duration: float) -> None:
    """Issue 47 point 4: start-up and the agents' memory per robot against team size, one
    process per robot (the baseline) and the team in one host, the same instance each."""
    for n in sizes:
        inst = instance(folder, n, n)
        one = demo(inst, folder / f"s{n}-k1", arch, 1, duration)
        host = demo(inst, folder / f"s{n}-k{n}", arch, n, duration)

        def per_robot(r: dict) -> float | None:
            return None if r["agents_rss_kb"] is None else round(r["agents_rss_kb"] / 1024 / n, 2)
        emit(figure="startup", architecture=arch, robots=n, tasks=n, duration=duration,
             per_process_startup_s=one["startup_s"], hosted_startup_s=host["startup_s"],
             per_process_rss_mb_per_robot=per_robot(one), hosted_rss_mb_per_robot=per_robot(host),
             per_process_wall_s=one["wall_s"], hosted_wall_s=host["wall_s"],
             per_process_agents_cpu_s=one["cpu_by_role"].get("agents"),
             hosted_agents_cpu_s=host["cpu_by_role"].get("agents"),
             status=[one["summary"].get("run_status"), host["summary"].get("run_status")],
             rc=[one["rc"], host["rc"]], error=one["error"] + host["error"])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--duration", type=float, default=30.0)
    ap.add_argument("--architecture", default="cbba", help="run_cost's architecture")
    ap.add_argument("--sizes", type=int, nargs="*", default=[])
    ap.add_argument("--architectures", nargs="+", default=["cbba", "alliance"])
    ap.add_argument("--per-host", type=int, default=0, help="robots per host (0: the team)")
    ap.add_argument("--startup-sizes", type=int, nargs="*", default=[],
                    help="team sizes for the start-up and memory figure (point 4)")
    ap.add_argument("--startup-duration", type=float, default=2.0)
    ap.add_argument("--hear-sizes", type=int, nargs="*", default=[],
                    help="subscriptions per bus for the own_delivery figure")
    args = ap.parse_args()
    if args.hear_sizes:
        own_delivery(args.hear_sizes)
        remote_delivery(args.hear_sizes)
    with tempfile.TemporaryDirectory(prefix="mrta-hosts-") as tmp:
        folder = Path(tmp)
        if args.repeat:
            run_cost(folder, args.repeat, args.duration, args.architecture)
        if args.startup_sizes:
            startup(folder, args.startup_sizes, args.architecture, args.startup_duration)
        if args.sizes:
            team_size(folder, args.sizes, args.architectures, args.per_host, args.duration)


if __name__ == "__main__":
    main()
