"""ALLIANCE (Parker 1998; the dissertation's `alliance` package) on the agent runtime.

This folder is also its rqt_mrta package (package.xml, rqt_mrta.xml: the supervisor's monitors
and the parameter templates, launch/alliance.launch), registered under `mrta.packages` as
`alliance`; its contract object (architecture.ALLIANCE) is registered under
`mrta.architectures`. high_level.py is the motivational logic on virtual time, agent.py what the
runtime's driver is given, params.py the dissertation's YAML layout.
"""
