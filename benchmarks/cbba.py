"""CBBA's decision cost and convergence against team and task counts: `python benchmarks/cbba.py`.

For each (N robots, M tasks) and seed, a random open-world instance (a 50 m square, speeds
0.5–1.5 m/s, rewards 1, every task known at 0; `--timed`: arrivals, service times and rewards
that differ, all known at 0) is allocated by CBBA in the paper's synchronous
rounds on a full graph (mrta_agent.cbba.synchronous, the same logic an agent runs), and by the
sequential greedy algorithm (SGA, mrta_zenoh.planning.insertion) — the centralised computation
CBBA provably reproduces — in the same run. Figures, one JSON line per (N, M):

    round_ms          one robot's iteration (the messages it heard, release, re-check, bundle
                      construction): median and largest over every robot and round
    first_round_ms    the largest of round 1, when every robot builds its bundle from nothing
    rounds            rounds until the last change (round 1 included; the paper's bound is
                      1 + min(N_t, L_t·N_u)·D, D = 1 here), median and largest over seeds
    team_ms           the sum of every robot's iterations until convergence (the team's work)
    sga_ms            SGA on the same instance (one process doing all of it)
    message_bytes     a converged robot's Bids message, encoded (mrta_zenoh.codec)
    same_as_sga       seeds whose converged paths are SGA's (on the score the rules bid)
    unsettled         seeds where the team did not settle within 500 rounds

`--rules published` runs the paper's rules (its marginal score, no re-check: docs/cbba.md,
"Where we depart from the paper"), `no-recheck` and `no-diminishing` one departure each.

Times are wall seconds of this process (medians over seeds) and vary with the machine and what
runs beside it; compare them with sga_ms of the same line, measured in the same run.

    python benchmarks/cbba.py                                   # N 2, 4, 8 × M 10, 20, 40
    python benchmarks/cbba.py --robots 4 --tasks 80 --bundle-limit 5 --seeds 2
    python benchmarks/cbba.py --robots 2 3 4 5 --tasks 3 6 9 --seeds 40 --rules published --timed
"""

from __future__ import annotations

import argparse
import json
import math
import random
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from mrta_agent.cbba.bundle import Cbba  # noqa: E402
from mrta_agent.cbba.messages import Bids  # noqa: E402
from mrta_agent.cbba.synchronous import run_rounds  # noqa: E402
from mrta_zenoh.codec import encode  # noqa: E402
from mrta_zenoh.messages import Header  # noqa: E402
from mrta_zenoh.planning import Problem, Robot, Task  # noqa: E402
from mrta_zenoh.planning.insertion import sequential_greedy  # noqa: E402

DISCOUNT = 0.95
RULES = {"ours": (True, True), "published": (False, False), "no-recheck": (True, False),
         "no-diminishing": (False, True)}  # (diminishing, recheck)


def instance(n: int, m: int, seed: int, timed: bool) -> Problem:
    rng = random.Random(seed * 1_000 + n * 100 + m)
    robots = tuple(Robot(f"r{i}", (rng.uniform(0, 50), rng.uniform(0, 50)),
                         rng.uniform(0.5, 1.5)) for i in range(n))
    if not timed:
        return Problem(robots, tuple(Task(f"t{j:03d}", (rng.uniform(0, 50), rng.uniform(0, 50)))
                                     for j in range(m)))
    return Problem(robots, tuple(Task(f"t{j:03d}", (rng.uniform(0, 50), rng.uniform(0, 50)),
                                      arrival=rng.uniform(0, 60), service=rng.uniform(0, 5),
                                      reward=rng.uniform(0.5, 2.0)) for j in range(m)))


def one(n: int, m: int, seed: int, limit: int | None, rules: str,
        timed: bool) -> dict | None:
    """One instance's figures; None if the team did not settle."""
    p = instance(n, m, seed, timed)
    diminishing, recheck = RULES[rules]
    team = {r.id: Cbba(p, r.id, discount=DISCOUNT, bundle_limit=limit, resend_period=0.0,
                       lookahead=math.inf, diminishing=diminishing, recheck=recheck)
            for r in p.robots}
    timings: list[tuple[int, str, float]] = []
    try:
        rounds = run_rounds(team, timings=timings, max_rounds=500)
    except RuntimeError:
        return None
    converged = [t for rnd, _, t in timings if rnd <= rounds]
    began = time.perf_counter()
    routes, _ = sequential_greedy(p, DISCOUNT, limit=limit, diminishing=diminishing)
    sga = time.perf_counter() - began
    fields = team["r0"].tick(10_000.0)[0].fields
    return {"round": [t for _, _, t in timings], "first": max(t for r, _, t in timings if r == 1),
            "rounds": rounds, "team": sum(converged), "sga": sga,
            "bytes": len(encode(Bids(header=Header("r0", 10_000.0, 1), **fields))),
            "same": {p.robot_index(r): c.path for r, c in team.items()} == routes}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robots", type=int, nargs="+", default=[2, 4, 8])
    ap.add_argument("--tasks", type=int, nargs="+", default=[10, 20, 40])
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--bundle-limit", type=int, default=None)
    ap.add_argument("--rules", choices=sorted(RULES), default="ours")
    ap.add_argument("--timed", action="store_true",
                    help="tasks arrive over 60 s, take 0–5 s of service, rewards 0.5–2")
    args = ap.parse_args()
    for n in args.robots:
        for m in args.tasks:
            every = [one(n, m, seed, args.bundle_limit, args.rules, args.timed)
                     for seed in range(args.seeds)]
            runs = [r for r in every if r is not None]
            ticks = [t for r in runs for t in r["round"]]
            ms = lambda xs: round(1e3 * statistics.median(xs), 3)  # noqa: E731
            print(json.dumps({
                "figure": "cbba", "robots": n, "tasks": m, "bundle_limit": args.bundle_limit,
                "rules": args.rules, "timed": args.timed, "seeds": args.seeds,
                "round_ms": {"median": ms(ticks), "max": round(1e3 * max(ticks), 3)},
                "first_round_ms": ms([r["first"] for r in runs]),
                "rounds": {"median": statistics.median(r["rounds"] for r in runs),
                           "max": max(r["rounds"] for r in runs),
                           "bound": 1 + min(m, (args.bundle_limit or m) * n)},
                "team_ms": ms([r["team"] for r in runs]),
                "sga_ms": ms([r["sga"] for r in runs]),
                "message_bytes": statistics.median(r["bytes"] for r in runs),
                "same_as_sga": sum(r["same"] for r in runs),
                "unsettled": len(every) - len(runs)}), flush=True)


if __name__ == "__main__":
    main()
