"""Sequential single-item auctions (SSI; Lagoudakis et al., "Auction-based multi-robot routing",
RSS 2005; Koenig, Tovey et al., "The power of sequential single-item auctions for agent
coordination", AAAI 2006) for time-extended allocation (ST-SR-TA): in each round every robot
bids what its best unallocated task would add to its own path (the MinSum rule), and the lowest
bid wins that one task; rounds go on until every task is allocated.

The decision logic, pure on virtual time (`auction.Ssi`), and its wire messages
(`messages.Round`, `messages.Bid`). docs/ssi.md tells the protocol on the bus, its tie rules
and why one auctioneer clears the rounds.
"""
