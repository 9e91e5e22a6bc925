"""`mrta --help`: CPU seconds to list the commands.

Prints one JSON line per figure, each the median of alternating rounds (this machine's load
swings a single run by tens of percent): `mrta --help` as it is (its lines from
mrta_zenoh.cli.main.SHORT_HELP, no command imported); the baseline in the same run — the same
listing after importing every command, which is what `--help` did before; and the interpreter
alone (`python -c pass`), the floor no listing goes under.

Run: python benchmarks/cli_help.py [--rounds 7]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys

HERE = os.path.abspath(__file__)
sys.path[:] = [p for p in sys.path if os.path.abspath(p or ".") != os.path.dirname(HERE)]

EVERY_COMMAND_IMPORTED = (
    "from importlib.metadata import entry_points\n"
    "from mrta_zenoh.cli.main import cli\n"
    "for ep in entry_points(group='mrta.commands'):\n"
    "    ep.load()\n"
    "cli.main(['--help'], prog_name='mrta', standalone_mode=False)\n")


def cpu_seconds(argv: list[str]) -> float:
    """User + system CPU seconds of one run of `argv` (its output discarded)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run(argv, stdout=subprocess.DEVNULL, check=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rounds", type=int, default=7)
    rounds = ap.parse_args().rounds
    mrta = os.path.join(os.path.dirname(sys.executable), "mrta")
    cases = {
        "mrta --help": [mrta, "--help"],
        "every command imported, then --help (before)": [sys.executable, "-c",
                                                         EVERY_COMMAND_IMPORTED],
        "python -c pass (floor)": [sys.executable, "-c", "pass"],
    }
    times: dict[str, list[float]] = {k: [] for k in cases}
    cpu_seconds(cases["mrta --help"])  # warm the page cache and the bytecode
    for _ in range(rounds):
        for name, argv in cases.items():
            times[name].append(cpu_seconds(argv))
    ours = statistics.median(times["mrta --help"])
    for name, values in times.items():
        print(json.dumps({"figure": f"CPU seconds: {name}", "median": round(statistics.median(
            values), 3), "min": round(min(values), 3), "max": round(max(values), 3),
            "rounds": rounds, "ratio_to_mrta_help": round(statistics.median(values) / ours, 2)}),
            flush=True)


if __name__ == "__main__":
    main()
