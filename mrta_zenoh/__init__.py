"""mrta_zenoh: the core of mrta-zenoh — messages, codec, bus, keys, field paths, clocks, config.

It knows nothing of ALLIANCE's logic; robot_agent, simulator and supervisor build on it.
"""

__version__ = "0.1.0"
