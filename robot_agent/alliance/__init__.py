"""The ALLIANCE architecture as an rqt_mrta package: package.xml, rqt_mrta.xml (the supervisor's
monitors, the parameter templates) and launch/alliance.launch. Registered under `mrta.packages`
as `alliance`; it holds no code."""
