"""mrta_delivery: point-task delivery missions (ST-SR-IA) with an optimal baseline — docs/delivery.md.

Single-task robots, single-robot tasks at points of a small open world: a task appears at its
arrival time, needs a robot with its capability to drive there and stay for its service time.
One rqt_mrta application package per architecture, generated from one instance
(`config/instance.yaml`, by `python -m mrta_delivery.generate_cli`): `delivery` (ALLIANCE) and
`delivery_murdoch` (MURDOCH). Like patrol it plugs in through entry points only and reaches an
architecture only through its contract; the framework never imports it.
"""
