"""A forger of coordination messages on the fleet's bus (issue 51): publishes, with raw
zenoh-python and msgpack (no mrta code on the send path), once, what the hostile probe sent under
the demo's keys — copied from a real message of the run, so that its header (sender, stamp) is
plausible.

argv: MODE ARG RENDEZVOUS (the run's, which this session connects to)
  central-served  TASKS   a `Progress` of robot2's saying every task of TASKS (comma-separated)
                          served (it crashed the dispatcher)
  ssi-round       -       a `Round` of robot1's (the auctioneer) numbered 2^62
Prints {"ready": true} once subscribed, {"forged": KEY} once sent."""

import json
import sys
import threading
import time

import msgpack
import zenoh

from mrta_zenoh.bus import BusOptions
from mrta_zenoh.bus.zenoh_bus import open_session

mode, arg, rendezvous = sys.argv[1], sys.argv[2], sys.argv[3]
session = open_session(BusOptions(connect=[rendezvous]))
ENC = "application/msgpack;"
SOURCES = {"central-served": ("robot2/central/progress", "route_msgs/Progress"),
           "ssi-round": ("robot1/ssi/round", "ssi_msgs/Round")}
key, type_name = SOURCES[mode]
real: list[dict] = []
heard = threading.Event()


def on_sample(sample) -> None:
    if not heard.is_set():
        real.append(msgpack.unpackb(sample.payload.to_bytes()))
        heard.set()


sub = session.declare_subscriber(key, on_sample)
print(json.dumps({"ready": True}), flush=True)
heard.wait(120)
msg = dict(real[0])
msg["header"] = {**msg["header"], "seq": msg["header"]["seq"] + 1000}
if mode == "central-served":
    msg["served"] = arg.split(",")
else:
    msg["round"] = 2 ** 62
    msg["owners"] = [-1] * len(msg["owners"])
    msg["award"] = -1
pub = session.declare_publisher(key, congestion_control=zenoh.CongestionControl.BLOCK)
time.sleep(0.3)  # the publisher's matching declarations travel first
pub.put(msgpack.packb(msg), encoding=zenoh.Encoding(ENC + type_name))
print(json.dumps({"forged": key}), flush=True)
time.sleep(1.0)
session.close()
