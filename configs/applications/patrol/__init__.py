"""mrta_patrol: the dissertation's patrol application (three Pioneers: wander, border protection,
report) as one package — its rqt_mrta application files (package.xml, rqt_mrta.xml, config/,
launch/), its world (worlds/patrol.yaml) and its Python plugins, messages and demo.

It plugs in exactly as a third party's application would: through entry points only
(`mrta.packages`, `mrta.messages`, `mrta.alliance.*`, `mrta.commands` for `mrta demo`). The
framework (mrta_zenoh, robot_agent, simulator, supervisor) never imports it.
"""
