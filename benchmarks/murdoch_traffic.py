"""MURDOCH's coordination messages heard per robot: `python benchmarks/murdoch_traffic.py`.

Runs one `mrta demo` per mission under MURDOCH (lockstep, no fault, as fast as possible: a
run's outcome depends on its seed only) and counts, from its recording, the coordination
messages each robot received from its teammates per simulated second, by kind:

    subjects   what MURDOCH's subscriptions deliver (docs/murdoch.md, Protocol): a task's
               announcements reach the robots with a skill for it, a bid its auctioneer only,
               awards, claims and releases every robot;
    broadcast  the baseline, from the same recording: every coordination message heard by every
               other robot (all-hear-all, what MURDOCH did before subjects).

Both count the very messages the run sent, so the ratio is the addressing alone. It also prints
when each task was first announced and by whom, and the run's allocation figures (makespan,
optimality, mean waiting time, first full allocation: summary.json).

One JSON line per figure on stdout; each demo's own output goes to OUTPUT/<mission>/demo.log.

    python benchmarks/murdoch_traffic.py                       # delivery and patrol, 60 s, seed 0
    python benchmarks/murdoch_traffic.py --missions delivery --output /tmp/traffic --reuse
"""

from __future__ import annotations

import argparse
import collections
import json
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from mrta_agent.murdoch.architecture import MURDOCH  # noqa: E402
from mrta_agent.murdoch.params import load_robot  # noqa: E402
from mrta_supervisor.mission.hook import MissionOptions, resolve  # noqa: E402
from mrta_zenoh.codec import decoder_for  # noqa: E402
from mrta_zenoh.keys import first_chunk  # noqa: E402
from mrta_zenoh.recording import read_recording  # noqa: E402

KINDS = ("announcement", "bid", "award", "claim", "release")
ALLOCATION = ("makespan", "optimality", "mean_waiting_time", "completed", "tasks")


def run_demo(mission: str, out: Path, duration: float, seed: int) -> None:
    """`mrta demo` of `mission` under MURDOCH into `out` (its output in out/demo.log)."""
    mrta = Path(sys.executable).parent / "mrta"
    out.mkdir(parents=True, exist_ok=True)
    cmd = [str(mrta), "demo", "--application", mission, "--architecture", MURDOCH.name,
           "--fail", "none", "--speed", "0", "--duration", f"{duration:g}", "--seed", str(seed),
           "--no-live", "--lockstep", "--output", str(out)]
    with open(out / "demo.log", "w") as log:
        subprocess.run(cmd, stdout=log, stderr=subprocess.STDOUT, check=True, cwd=ROOT)


def served(mission: str) -> dict[str, set[str]]:
    """Each robot's subjects: the tasks it has a skill for (level > 0), from its parameters."""
    run = resolve(MissionOptions(application=mission, architecture=MURDOCH.name))
    return {r: {s.task_id for s in load_robot(run.robot_params(r))[0].skills if s.level > 0}
            for r in run.robots}


def hears(robot: str, serves: set[str], sender: str, kind: str, sub: str | None) -> bool:
    """Whether `robot`'s subscriptions deliver a `kind` message of `sender` on sub-key `sub`."""
    if robot == sender:
        return False
    if kind == "announcement":
        return sub in serves
    if kind == "bid":
        return sub == robot
    return True


def count(recording: Path, serves: dict[str, set[str]]):
    """(heard by subjects, heard by broadcast: robot → kind → count; first announcement per
    task: task → (stamp, robot))."""
    subjects = {r: collections.Counter() for r in serves}
    broadcast = {r: collections.Counter() for r in serves}
    first: dict[str, tuple[float, str]] = {}
    decoders: dict[str, object] = {}
    for key, enc, _t, payload in read_recording(recording):
        if not MURDOCH.is_coordination_key(key):
            continue
        chunks = key.split("/")
        sender, kind = first_chunk(key), chunks[2]
        sub = chunks[3] if len(chunks) > 3 else None
        for r in serves:
            if r != sender:
                broadcast[r][kind] += 1
            if hears(r, serves[r], sender, kind, sub):
                subjects[r][kind] += 1
        if kind == "announcement":
            if enc not in decoders:
                decoders[enc] = decoder_for(enc)[1]
            msg = decoders[enc](payload)
            stamp = msg.header.stamp
            if msg.task_id not in first or stamp < first[msg.task_id][0]:
                first[msg.task_id] = (stamp, sender)
    return subjects, broadcast, first


def per_second(heard: dict[str, collections.Counter], kinds, duration: float) -> list[float]:
    return [sum(heard[r][k] for k in kinds) / duration for r in sorted(heard)]


def figures(mission: str, out: Path, duration: float) -> list[dict]:
    serves = served(mission)
    subjects, broadcast, first = count(out / "run.mcap", serves)
    rows = []
    for kind in (*KINDS, "total"):
        kinds = KINDS if kind == "total" else (kind,)
        sub, bro = per_second(subjects, kinds, duration), per_second(broadcast, kinds, duration)
        mean_s, mean_b = sum(sub) / len(sub), sum(bro) / len(bro)
        rows.append({"mission": mission, "figure": "heard per robot per s", "kind": kind,
                     "subjects": round(mean_s, 3), "subjects_min": round(min(sub), 3),
                     "subjects_max": round(max(sub), 3), "broadcast": round(mean_b, 3),
                     "ratio": round(mean_s / mean_b, 3) if mean_b else None,
                     "per_robot": dict(zip(sorted(subjects), (round(x, 3) for x in sub)))})
    for task, (stamp, robot) in sorted(first.items()):
        rows.append({"mission": mission, "figure": "first announcement", "task": task,
                     "at": round(stamp, 3), "by": robot})
    summary = json.loads((out / "summary.json").read_text())
    metrics = summary.get("metrics") or {}
    rows.append({"mission": mission, "figure": "allocation",
                 "first_full_allocation": summary.get("first_full_allocation"),
                 **{k: metrics[k] for k in ALLOCATION if k in metrics},
                 "assigned_at": {a["task"]: [a["robot"], a["assigned_at"]]
                                 for a in summary.get("allocation") or []}})
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--missions", nargs="+", default=["delivery", "patrol"])
    ap.add_argument("--duration", type=float, default=60.0, help="simulated seconds per run")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--output", type=Path, default=None,
                    help="folder for the runs (default: a new temporary one)")
    ap.add_argument("--reuse", action="store_true",
                    help="count an existing OUTPUT/<mission>/run.mcap instead of running again")
    args = ap.parse_args()
    output = args.output or Path(tempfile.mkdtemp(prefix="murdoch_traffic_"))
    for mission in args.missions:
        out = output / mission
        if not (args.reuse and (out / "run.mcap").exists()):
            run_demo(mission, out, args.duration, args.seed)
        for row in figures(mission, out, args.duration):
            print(json.dumps(row), flush=True)
    print(json.dumps({"figure": "runs", "output": str(output), "duration": args.duration,
                      "seed": args.seed}), flush=True)


if __name__ == "__main__":
    main()
