"""A certified robot forging central's and delivery's messages on a secured fleet (issue 51.4):
with robot1's own fleet config (its certificate), raw zenoh-python and msgpack, once the run's
clock has passed 2 s, it sends

* a `Queue` to robot2 under the dispatcher's key `dispatcher/central/queue/robot2` (the router
  must drop it: only the dispatcher's certificate publishes there),
* the same `Queue` under its own key `robot1/central/queue/robot2` (it arrives: robot2 must
  refuse it, not its dispatcher),
* a copy of robot1's latest `Progress` claiming `SERVED` (comma-separated) served,
* a `TaskEvent done` for task `DONE`, which robot1 never started.

Each forged header has seq MARK, so the test can tell them from the real ones.
argv: CONFIG SERVED DONE. Prints {"ready": true}, then {"forged": [keys]}."""

import json
import sys
import threading
import time

import msgpack
import zenoh

from mrta_zenoh.bus import BusOptions
from mrta_zenoh.bus.zenoh_bus import open_session

MARK = 7_777_777
ENC = "application/msgpack;"
config, served, done_task = sys.argv[1], sys.argv[2].split(","), sys.argv[3]
session = open_session(BusOptions(zenoh_config=config))
now = [0.0]
progress: list[dict] = []
ready = threading.Event()


def on_clock(sample) -> None:
    now[0] = msgpack.unpackb(sample.payload.to_bytes())["stamp"]
    if now[0] >= 2.0 and progress:
        ready.set()


subs = [session.declare_subscriber("clock", on_clock),
        session.declare_subscriber("robot1/central/progress", lambda s: progress.append(
            msgpack.unpackb(s.payload.to_bytes())))]
print(json.dumps({"ready": True}), flush=True)
ready.wait(180)


def put(key: str, type_name: str, body: dict) -> None:
    pub = session.declare_publisher(key, congestion_control=zenoh.CongestionControl.BLOCK)
    time.sleep(0.3)  # the publisher's matching declarations travel first
    pub.put(msgpack.packb(body), encoding=zenoh.Encoding(ENC + type_name))


header = {"frame_id": "dispatcher", "stamp": now[0], "seq": MARK}
queue = {"header": header, "robot": "robot2", "version": 2 ** 40, "tasks": []}
put("dispatcher/central/queue/robot2", "central_msgs/Queue", queue)
put("robot1/central/queue/robot2", "central_msgs/Queue",
    {**queue, "header": {**header, "frame_id": "robot1"}})
report = dict(progress[-1])
report["header"] = {**report["header"], "seq": MARK}
report["served"] = list(report["served"]) + served
put("robot1/central/progress", "route_msgs/Progress", report)
put("robot1/delivery/done", "delivery_msgs/TaskEvent",
    {"header": {"frame_id": "robot1", "stamp": now[0], "seq": MARK}, "task_id": done_task,
     "event": "done"})
print(json.dumps({"forged": True}), flush=True)
time.sleep(1.0)
session.close()
