"""pymunk simulator: Pioneer 3-DX robots with sonar and odometry in MobileSim or YAML worlds."""
