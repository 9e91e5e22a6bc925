"""mrta_agent: the robot agent runtime and the MRTA architectures that run on it, side by side.

`runtime/` knows no architecture: the one agent driver (loop.Agent), its hosting, plugins and
their parameters, the agent verbs' options, and the agent side of the architecture contract.
`alliance/` (Parker's ALLIANCE) and `murdoch/` (Gerkey & Matarić's MURDOCH) each hold their
rqt_mrta package data beside their code and register themselves under `mrta.architectures`;
docs/architecture.md says how to add another.
"""
