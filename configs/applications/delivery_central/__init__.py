"""The delivery mission under central: an rqt_mrta application package (registered under
`mrta.packages` as `delivery_central`) written, like `delivery` and `delivery_murdoch`, by
`python -m mrta_delivery.generate_cli` from the same instance — its rqt_mrta files from
`delivery_central_answers.yaml` through the toolchain's generator (`mrta app new --answers`
gives them byte for byte), its layers file, dispatcher launch and instance beside them. It
holds no code: its layers and evaluators are the delivery application's."""
