"""The Pioneer 3-DX as the simulator models it.

Sonar poses are ARIA's `p3dx.p` (SonarUnit x y theta, mm and degrees); the body is a circle that
contains every transducer, which is what matters for collisions and for being seen by others.
Speed and acceleration limits are ARIA's defaults for the P3-DX.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

# (x mm, y mm, theta deg): units 0-7 front ring, 8-15 rear ring, numbered as ARIA does.
P3DX_SONARS_MM_DEG = (
    (69, 136, 90), (114, 119, 50), (148, 78, 30), (166, 27, 10),
    (166, -27, -10), (148, -78, -30), (114, -119, -50), (69, -136, -90),
    (-157, -136, -90), (-203, -119, -130), (-237, -78, -150), (-255, -27, -170),
    (-255, 27, 170), (-237, 78, 150), (-203, 119, 130), (-157, 136, 90),
)


@dataclass(frozen=True)
class RobotModel:
    radius: float = 0.26          # m; contains every sonar transducer
    mass: float = 9.0             # kg
    max_linear: float = 0.75      # m/s (ARIA TransVelMax default)
    max_angular: float = math.radians(100.0)  # rad/s (RotVelMax)
    linear_accel: float = 0.3     # m/s² (TransAccel / TransDecel)
    angular_accel: float = math.radians(100.0)  # rad/s² (RotAccel / RotDecel)
    sonar_min: float = 0.1        # m
    sonar_max: float = 5.0        # m; "no echo" is reported as a point at exactly this range
    sonar_half_angle: float = math.radians(7.5)  # beam: MobileSim's 15° field of view
    sonar_noise: float = 0.01     # σ as a fraction of range
    sonar_noise_floor: float = 0.005  # σ added in metres
    odom_scale_sigma: float = 0.01    # per-robot systematic error on distance travelled
    odom_turn_sigma: float = 0.02     # per-robot systematic error on rotation
    odom_step_sigma: float = 0.005    # per-step random error, fraction of the motion
    watchdog: float = 0.5         # s without cmd_vel → stop
    rear_sonars: bool = False

    def sonar_poses(self) -> np.ndarray:
        """(K, 3): x, y in metres and theta in radians, robot frame."""
        units = P3DX_SONARS_MM_DEG if self.rear_sonars else P3DX_SONARS_MM_DEG[:8]
        arr = np.array(units, dtype=float)
        arr[:, :2] /= 1000.0
        arr[:, 2] = np.radians(arr[:, 2])
        return arr
