"""The route family: what the architectures whose robots serve an ordered route of point tasks
share (central, SSI, CBBA) and what the runtime, knowing no architecture, does not hold.

* `executor.py` — `RouteExecutor`, the route served one task after another on an injected time,
  and `PluginReadings`, the robot's plugins as the executor's readings; `route_tasks`, the
  robot file's tasks and pose topic.
* `messages.py` — `route_msgs/Progress` and `route_msgs/Queued`, a route-serving robot's reports.
* `architecture.py` — `RouteArchitecture`, the contract object such an architecture subclasses.
* `own_route.py`, `own_route_params.py`, `own_route_arch.py` — robots serving the route their own
  decision logic keeps (SSI, CBBA): the adapter between the logic and the executor, its parameter
  files, its contract object.

It builds on the runtime (`mrta_agent.runtime`) and knows no architecture; ALLIANCE and MURDOCH
do not use it (tests/test_layering.py).
"""
