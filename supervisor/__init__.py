"""Supervisor: robots busy / idle / offline, tasks, allocations and alarms from any architecture file."""
