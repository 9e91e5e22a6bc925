"""MURDOCH (Gerkey & Matarić, "Sold!: Auction methods for multirobot coordination", IEEE T-RA
2002) as a second architecture for mrta-zenoh: an rqt_mrta package (package.xml, rqt_mrta.xml,
launch/murdoch.launch) and its runtime, one `mrta murdoch` process per robot.

Registered under `mrta.packages` as `murdoch`. The runtime shares robot_agent's low level —
sensor, evaluator and layer plugins, the two-rate loop and its hosting — so an application's
layers (the patrol ones) run unchanged under either architecture. docs/murdoch.md tells the
protocol and where it departs from the paper.
"""
