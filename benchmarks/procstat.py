"""What a benchmark reads of a process it started, from /proc: CPU seconds, RSS, private pages.
Shared by benchmarks/agent.py and benchmarks/swarm.py (Linux only, like the machines they run on)."""

from __future__ import annotations

import os


def proc_stat(pid: int) -> tuple[float, int]:
    """CPU seconds (user + system) and RSS in bytes."""
    with open(f"/proc/{pid}/stat") as f:
        parts = f.read().rsplit(")", 1)[1].split()
    ticks = int(parts[11]) + int(parts[12])  # utime + stime
    with open(f"/proc/{pid}/status") as f:
        rss = next(int(line.split()[1]) for line in f if line.startswith("VmRSS:"))
    return ticks / os.sysconf("SC_CLK_TCK"), rss * 1024


def private_mb(pid: int) -> float:
    """Unique set size (private pages, MB): what one more such process adds to the machine —
    RSS also counts the interpreter's and Zenoh's shared library pages, paid once."""
    with open(f"/proc/{pid}/smaps_rollup") as f:
        fields = dict(line.split(":", 1) for line in f if ":" in line and "-" not in line[:12])
    return sum(int(fields[k].split()[0]) for k in ("Private_Clean", "Private_Dirty")) / 1024
