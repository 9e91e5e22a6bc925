"""The Consensus-Based Bundle Algorithm (Choi, Brunet & How, "Consensus-Based Decentralized
Auctions for Robust Task Allocation", IEEE T-RO 25(4), 2009) for time-extended allocation
(ST-SR-TA): each robot builds a bundle of tasks by marginal score and agrees with its neighbours
on who won what through the paper's conflict-resolution table.

The decision logic, pure on virtual time (`bundle.Cbba`), its wire message (`messages.Bids`),
Table 1 (`table.resolve`) and the paper's synchronous rounds (`synchronous.run_rounds`, for
tests and benchmarks). docs/cbba.md tells the algorithm, its guarantees and where we depart
from the paper.
"""
