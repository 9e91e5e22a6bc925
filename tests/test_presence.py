"""RobotPresence: a robot is up while any of its tokens is; infrastructure and strangers never
count. What `mrta sim --wait-robots` and the patrol demo's readiness both rely on."""

from mrta_zenoh.bus.inproc import InProcBus, InProcNetwork
from mrta_zenoh.presence import RobotPresence


def test_up_while_any_token_lives_and_only_for_known_robots():
    net = InProcNetwork()
    robot1, robot2, other = InProcBus(net), InProcBus(net), InProcBus(net)
    early = robot1.declare_token("robot1/alliance/agent")  # before the watch: history counts
    with RobotPresence(InProcBus(net), ["robot1", "robot2"]) as presence:
        assert presence.missing() == ["robot2"] and not presence.all_up()
        other.declare_token("@mrta/clock_source/run")
        other.declare_token("robot9/alliance/agent")
        assert presence.missing() == ["robot2"]
        presence.changed.clear()
        sensors = robot2.declare_token("robot2/sonar")
        agent = robot2.declare_token("robot2/alliance/agent")
        assert presence.all_up() and presence.changed.is_set()
        agent.close()
        assert presence.all_up()  # its sensor node still holds one
        sensors.close()
        assert presence.missing() == ["robot2"]
        early.close()
        assert presence.missing() == ["robot1", "robot2"]
        # gone: up once, then not (the snapshot draws a crashed robot so); never up is not gone
    with RobotPresence(InProcBus(net), ["robot1", "robot3"]) as presence:
        token = robot1.declare_token("robot1/alliance/agent")
        assert presence.gone() == []
        token.close()
        assert presence.gone() == ["robot1"] and presence.missing() == ["robot1", "robot3"]
