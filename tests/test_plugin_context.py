"""What a robot's plugins share: the context's blackboard (`AgentContext.share`), made once by
the first plugin to ask; and what a plugin opens through its base (`subscribe`,
`watch_liveliness`) is closed by `shutdown()` — no attribute hung on the context, no private
list reached into."""

import numpy as np

from mrta_zenoh.bus import InProcBus, InProcNetwork
from mrta_zenoh.clock import ManualClock
from mrta_zenoh.messages import Twist
from mrta_agent.runtime.plugins import AgentContext, Plugin


def context(bus) -> AgentContext:
    return AgentContext("robot1", bus, ManualClock(0.0), np.random.default_rng(0))


def test_the_blackboard_makes_a_value_once_and_every_plugin_gets_it():
    ctx, made = context(InProcBus()), []

    def make():
        made.append(1)
        return {"done": set()}

    first, second = ctx.share("app.board", make), ctx.share("app.board", make)
    assert first is second and made == [1] and ctx.shared["app.board"] is first
    assert ctx.share("app.nothing", lambda: None) is None
    assert ctx.share("app.nothing", lambda: 1 / 0) is None  # None is a value made, not made again


def test_what_a_plugin_opens_through_its_base_is_closed_at_shutdown():
    net = InProcNetwork()
    bus, other = InProcBus(net), InProcBus(net)
    plugin, heard, tokens = Plugin(), [], []
    plugin.setup(context(bus))
    plugin.subscribe("robot2/x", heard.append)
    plugin.watch_liveliness("robot2/**", lambda key, alive: tokens.append((key, alive)))
    token = other.declare_token("robot2/agent")
    other.publish("robot2/x", Twist(1.0, 0.0))
    assert len(heard) == 1 and tokens == [("robot2/agent", True)]
    plugin.shutdown()
    other.publish("robot2/x", Twist(2.0, 0.0))
    token.close()
    assert len(heard) == 1 and tokens == [("robot2/agent", True)]
