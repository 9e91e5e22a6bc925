"""The dispatcher's role in a secured fleet (`mrta secure init --process dispatcher`,
docs/security.md), registered under the `mrta.secure.roles` entry points as the simulator's is:
the keys it publishes and the tokens it holds are stated here, beside the code that uses them.

Only the dispatcher publishes queues: they are under its own name (`dispatcher/central/queue/
<robot>`), which no robot's certificate may publish on (a robot's is `robotN/**` only); a robot
publishes only its own progress (`robotN/central/progress`, its role). What it may publish:
everything under its name (its queues, its decisions, its refusal and fault tallies) and its
lockstep answers; its tokens: its process token (`@mrta/node/dispatcher`, what its robots
know it is up by) and its lockstep participant's.
"""

from __future__ import annotations

from mrta_zenoh.lockstep.protocol import DONE, PARTICIPANT

from .architecture import CENTRAL, DISPATCHER


def role() -> dict[str, list[str]]:
    return {"publish": [f"{DISPATCHER}/**", f"{DONE}/{DISPATCHER}"],
            "tokens": [CENTRAL.process_token(DISPATCHER), f"{PARTICIPANT}/{DISPATCHER}"]}
