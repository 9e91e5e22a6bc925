"""MURDOCH (Gerkey & Matarić, "Sold!: Auction methods for multirobot coordination", IEEE T-RA
2002) as a second architecture for mrta-zenoh: an rqt_mrta package (package.xml, rqt_mrta.xml,
launch/murdoch.launch) and its runtime, one `mrta murdoch` process per robot.

Registered under `mrta.packages` and `mrta.architectures` (architecture.MURDOCH) as `murdoch`.
It runs on the agent runtime's driver like ALLIANCE — the same plugins, inbox, team, loop and
hosting — so an application's layers (the patrol ones) run unchanged under either architecture. docs/murdoch.md tells the
protocol and where it departs from the paper.
"""
