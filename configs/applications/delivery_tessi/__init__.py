"""The delivery mission under TeSSI: an rqt_mrta application package (registered under
`mrta.packages` as `delivery_tessi`) written, like `delivery_central`, by
`python -m mrta_delivery.generate_cli` from the same instance — its rqt_mrta files from
`delivery_tessi_answers.yaml` through the toolchain's generator (`mrta app new --answers`
gives them byte for byte), its layers file, launch and the instance its robots plan on beside
them. It holds no code: its layers and evaluators are the delivery application's."""
