"""A stand-in of rmw_zenohd, the router every rmw_zenoh robot runs: router mode with the
settings of rmw_zenoh's DEFAULT_RMW_ZENOH_ROUTER_CONFIG.json5 that matter here — gossip on, no
multihop, and `peers_failover_brokering: false` (it does not broker between peers) — on a given
loopback port instead of 7447, multicast scouting off.

    ros2_rmw_router.py PORT      prints {"ready": true} once it listens, then runs until killed
"""

import json
import sys
import threading

import zenoh


def main(port: str) -> None:
    zenoh.init_log_from_env_or("error")
    conf = zenoh.Config()
    for key, value in {
        "mode": "router",
        "listen/endpoints": [f"tcp/127.0.0.1:{int(port)}"],
        "scouting/multicast/enabled": False,
        "scouting/gossip": {"enabled": True, "multihop": False,
                            "autoconnect": {"router": [], "peer": ["router", "peer"]}},
        "routing/router/peers_failover_brokering": False,
    }.items():
        conf.insert_json5(key, json.dumps(value))
    with zenoh.open(conf):
        print(json.dumps({"ready": True}), flush=True)
        threading.Event().wait()


if __name__ == "__main__":
    main(*sys.argv[1:])
