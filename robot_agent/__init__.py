"""robot_agent: one robot's ALLIANCE agent (high and low levels) on the mrta_zenoh bus."""
