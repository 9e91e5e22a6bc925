"""mrta_patrol: the dissertation's patrol application (three Pioneers: wander, border protection,
report) as one package — its rqt_mrta application files (package.xml, rqt_mrta.xml, config/,
launch/), its world (worlds/patrol.yaml) and its Python plugins, messages and mission hook.

It plugs in exactly as a third party's application would: through entry points only
(`mrta.packages`, `mrta.messages`, `mrta.plugins.*`, `mrta.missions` for `mrta demo`), and it
reaches an architecture only through the contract (mrta_zenoh.architectures). The framework
(mrta_zenoh, mrta_agent, mrta_simulator, mrta_supervisor) never imports it.
"""
