"""An agent process loads only what a robot needs (issue #27): no numpy unless a plugin draws
random numbers, and none of the observers' libraries (plotting, Foxglove, ROS 2 bags, rich,
certificates) at all. Checked in a fresh interpreter, where `sys.modules` tells the truth."""

import subprocess
import sys
import zlib

import numpy as np
import pytest

from mrta_zenoh.seeds import robot_rng

# _hashlib is OpenSSL's (≈ 3 MB of RSS): fault draws hash with _blake2 alone (mrta_zenoh.seeds)
HEAVY = ("numpy", "matplotlib", "rich", "foxglove", "rosbags", "cryptography", "scipy",
         "pymunk", "mcap", "distributed", "_hashlib")

PROBE = """
import sys
import mrta_agent.alliance.cli, mrta_agent.murdoch.cli
from mrta_agent.runtime import builtin
import mrta_patrol.evaluators
from mrta_zenoh.bus import zenoh_bus
from mrta_zenoh.seeds import robot_rng
from mrta_zenoh.failure import FaultPlan
rng = robot_rng(0, "robot1")
FaultPlan("robot1", 0, loss=0.5, latency=(0.2, 0.1)).lost("robot2/alliance/x", 1)
FaultPlan("robot1", 0, loss=0.5, latency=(0.2, 0.1)).delay("robot2/alliance/x", 1)
heavy = sorted({m.split('.')[0] for m in sys.modules} & set(sys.argv[1:]))
print(",".join(heavy))
"""


@pytest.mark.multiprocess
def test_agent_modules_load_no_heavy_library():
    out = subprocess.run([sys.executable, "-c", PROBE, *HEAVY], capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == ""


def test_a_lazy_stream_draws_the_numbers_an_eager_one_would():
    lazy = robot_rng(7, "robot2")
    # the derivation the docs state: SeedSequence(seed, spawn_key=(crc32(robot id),))
    eager = np.random.default_rng(np.random.SeedSequence(7, spawn_key=(zlib.crc32(b"robot2"),)))
    assert "not yet drawn" in repr(lazy)
    assert [lazy.normal(0.0, 0.6) for _ in range(5)] == [eager.normal(0.0, 0.6) for _ in range(5)]
    assert lazy.integers(0, 1000, 10).tolist() == eager.integers(0, 1000, 10).tolist()
    assert robot_rng(7, "robot3").normal() != robot_rng(7, "robot2").normal()
