"""central: a dispatcher process that re-solves the time-extended allocation problem (ST-SR-TA)
at each task arrival, completion or robot loss with the reference solvers of
`mrta_zenoh.planning` and sends each robot its queue; robots serve their queues one task after
another (mrta_agent.route.executor) and report progress. An rqt_mrta package (package.xml,
rqt_mrta.xml, launch/central.launch and launch/dispatcher.launch) and its runtime: one
`mrta central` process per robot and one `mrta dispatcher`.

Registered under `mrta.packages` and `mrta.architectures` (architecture.CENTRAL) as `central`.
docs/central.md tells the protocol, its guarantees and where it departs from a textbook
centralised planner.
"""
