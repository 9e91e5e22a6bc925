"""TeSSI (Nunes & Gini, "Multi-Robot Auctions for Allocation of Tasks with Temporal
Constraints", AAAI 2015): sequential single-item auctions for tasks with time windows, each
robot's schedule a simple temporal network into which a task is inserted only where the network
stays consistent, the bid the makespan of the resulting network (TeSSIduo: combined with the
travel the task adds).

Built on SSI (mrta_agent.ssi) by composition and inheritance: the same rounds, auctioneer, wire
messages (ssi_msgs/Round, ssi_msgs/Bid on the `tessi` namespace) and rules of what a message is
believed for; only the bid differs (auction.Tessi, stn.Schedule). docs/tessi.md.
"""
