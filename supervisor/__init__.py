"""Supervisor: what a fleet does, watched live, run as a mission and compared over experiments.

Three rooms that share little: `live` (the live supervisor: robots busy / idle / offline, tasks,
allocations and alarms from any architecture file; `mrta supervise`, `mrta view`), `mission`
(one mission run end to end — `mrta demo` — and its summary.json), `experiment` (`mrta
experiment`: a matrix of mission runs, results.csv and its report). The layering runs one way:
the mission runner watches its run through the live supervisor; the experiment system starts
missions only through the runner's entry point and reads the summaries back; the live
supervisor knows no experiment (tests/test_layering.py).
"""
