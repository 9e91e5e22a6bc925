"""The delivery mission under MURDOCH: an rqt_mrta application package (registered under
`mrta.packages` as `delivery_murdoch`) written, like `delivery`, by `python -m
mrta_delivery.generate_cli` from the same instance. It holds no code: its layers and evaluators are
the delivery application's, found through their entry points."""
