"""The live supervisor: what the fleet is doing now, from the bus alone. It owns the picture —
robots Idle / Busy / Offline, tasks and allocations, alarms and their transition history — built
from the architecture file's monitors (monitors.py) by a strict sample intake (intake.py) into the
state (state.py), with robots and tasks outside the application reported, never pictured
(strangers.py), robots driven through ROS 2 (drivers.py) and an application's done / waiting
tasks (tasks.py, `TaskWatch`). It shows that picture as a terminal view (view.py, `mrta
supervise`: api.py, cli.py) and to Foxglove / Lichtblick (`mrta view`: viewer.py, foxglove.py,
foxglove_server.py). It knows no experiment and runs no mission: the mission runner attaches
it to a run, and of a mission it asks only the application's hook for its TaskWatch
(mrta_supervisor.mission.hook.application_watch).
"""
