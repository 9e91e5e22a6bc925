"""A forger on the fleet's bus (issues 23 and 42): publishes what an attacker on an open bus
would, with raw zenoh-python and msgpack (no mrta code on the send path), once a subscriber is
there.

argv: MODE RUN [N [CHARS]]
  step    RUN          one Step of the real run, stamp 1e9, step number 10**9
  ghost   RUN          one StepDone from `ghost` (no token) claiming 10**9 samples of robot1/cmd_vel
  creep   RUN N        N clock samples carrying the real run id, each 9.9 s ahead of the last, every
                       5 ms (the probe: 300 in 1.5 s), starting 9.9 s ahead of the latest real one
  copy    RUN          one real Step, copied as it came, with step number 10**9
  replay  RUN N        a whole-table Step (asked for with a participant token held a moment), kept
                       N seconds, then sent again as the next one: numbered and stamped as the
                       real one after the latest would be (its table, counts and digest old)
  claims  RUN N CHARS  holds the participant token `ghost` and answers every step at once,
                       claiming N keys `ghost/k…` of CHARS characters each, for 20 s
  descend RUN N        follows every StepDone of robot1 with a copy claiming 50 samples of
                       robot1/cmd_vel more than the real count it first saw, lowered by 1 every
                       5.2 s, for N seconds
$MRTA_FORGER_CONFIG: a Zenoh config file (a secured fleet's robot1.json5); `claims` then answers
as robot1 (its own certificate), claiming keys `robot1/k…`, without a token of its own.
Prints {"ready": true}, lines of what it did, and then {"done": n}."""

import json
import os
import sys
import threading
import time

import msgpack
import zenoh

from mrta_zenoh.bus import BusOptions
from mrta_zenoh.bus.zenoh_bus import open_session

mode, run = sys.argv[1], sys.argv[2]
count = int(sys.argv[3]) if len(sys.argv) > 3 else 1
chars = int(sys.argv[4]) if len(sys.argv) > 4 else 0
ENC = "application/msgpack;"
config = os.environ.get("MRTA_FORGER_CONFIG")
session = open_session(BusOptions(zenoh_config=config) if config else BusOptions())


def publisher(key):
    pub = session.declare_publisher(key, congestion_control=zenoh.CongestionControl.BLOCK)
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline:
        status = pub.matching_status
        if getattr(status, "matching", status) is True:
            break
        time.sleep(0.02)
    time.sleep(0.2)
    return pub


def encoding(type_name):
    return zenoh.Encoding(ENC + type_name)


def steps(on_step):
    """Real steps, decoded, to `on_step(dict)` (from a Zenoh thread)."""
    return session.declare_subscriber(
        "@mrta/lockstep/step", lambda s: on_step(msgpack.unpackb(s.payload.to_bytes())))


def next_step():
    got, heard = [], threading.Event()
    sub = steps(lambda s: (got.append(s), heard.set()))
    heard.wait(30)
    sub.undeclare()
    return got[0]


def say(**what):
    print(json.dumps(what), flush=True)


try:
    say(ready=True)
    if mode == "step":
        pub = publisher("@mrta/lockstep/step")
        pub.put(msgpack.packb({"stamp": 1e9, "step": 10**9, "counts": b"", "run": run,
                               "timeout": 2.5}), encoding=encoding("mrta_msgs/Step"))
    elif mode == "ghost":
        pub = publisher("@mrta/lockstep/done/ghost")
        pub.put(msgpack.packb({"participant": "ghost", "stamp": 0.0,
                               "sent": {"robot1/cmd_vel": 10**9}, "next": -1.0, "run": run}),
                encoding=encoding("mrta_msgs/StepDone"))
    elif mode == "copy":
        pub = publisher("@mrta/lockstep/step")
        real = next_step()
        pub.put(msgpack.packb({**real, "step": 10**9}), encoding=encoding("mrta_msgs/Step"))
        say(copied=real["step"], stamp=real["stamp"])
    elif mode == "replay":
        pub = publisher("@mrta/lockstep/step")
        whole, latest, stamp = [], [0], [0.0]

        def on_step(s):
            latest[0] = max(latest[0], s["step"])
            stamp[0] = max(stamp[0], s["stamp"])
            if s.get("base", 0) == 0 and not whole:
                whole.append(s)
        sub = steps(on_step)
        token = session.liveliness().declare_token("@mrta/lockstep/participant/spy")
        deadline = time.monotonic() + 30
        while not whole and time.monotonic() < deadline:
            time.sleep(0.01)
        token.undeclare()  # not waited for: it never answers
        time.sleep(count)
        pub.put(msgpack.packb({**whole[0], "step": latest[0] + 1, "stamp": stamp[0]}),
                encoding=encoding("mrta_msgs/Step"))
        sub.undeclare()
        say(replayed=whole[0]["step"], stamp=whole[0]["stamp"], keys=len(whole[0]["keys"]),
            as_step=latest[0] + 1)
    elif mode == "claims":
        name = "robot1" if config else "ghost"
        pub = publisher(f"@mrta/lockstep/done/{name}")
        claims = {f"{name}/k{i:05d}".ljust(chars, "x"): 1 for i in range(count)}

        def answer(s):
            pub.put(msgpack.packb({"participant": name, "stamp": s["stamp"], "sent": claims,
                                   "next": s["stamp"] + 0.1, "run": s["run"]}),
                    encoding=encoding("mrta_msgs/StepDone"))
        sub = steps(answer)
        token = None if config else \
            session.liveliness().declare_token("@mrta/lockstep/participant/ghost")
        say(claiming=count, chars=chars, name=name)
        time.sleep(20)
        sub.undeclare()
        if token is not None:
            token.undeclare()
    elif mode == "descend":
        pub = publisher("@mrta/lockstep/done/robot1")
        level, t0 = [None], time.monotonic()

        def on_done(sample):
            d = msgpack.unpackb(sample.payload.to_bytes())
            real = d["sent"].get("robot1/cmd_vel", 0)
            if level[0] is None:
                level[0] = real + 50
            claim = level[0] - int((time.monotonic() - t0) / 5.2)
            if claim == real:  # its own copy, or the real one caught up
                return
            pub.put(msgpack.packb({**d, "sent": {**d["sent"], "robot1/cmd_vel": claim}}),
                    encoding=encoding("mrta_msgs/StepDone"))
        sub = session.declare_subscriber("@mrta/lockstep/done/robot1", on_done)
        time.sleep(count)
        sub.undeclare()
    elif mode == "creep":
        latest = [0.0]
        heard = threading.Event()

        def on_clock(sample):
            stamp = msgpack.unpackb(sample.payload.to_bytes())["stamp"]
            latest[0] = max(latest[0], stamp)
            heard.set()
        sub = session.declare_subscriber("clock", on_clock)
        heard.wait(30)
        sub.undeclare()
        pub = publisher("clock")
        stamp = latest[0]
        for _ in range(count):
            stamp += 9.9
            pub.put(msgpack.packb({"stamp": stamp, "source": run}),
                    encoding=encoding("rosgraph_msgs/Clock"))
            time.sleep(0.005)
        say(forged_to=stamp, **{"from": latest[0]})
    time.sleep(0.5)
    say(done=count)
finally:
    session.close()
