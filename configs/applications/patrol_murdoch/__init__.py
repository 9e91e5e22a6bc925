"""The patrol mission under MURDOCH: an rqt_mrta application package (registered under
`mrta.packages` as `patrol_murdoch`) generated, every file of it, by `mrta app new --answers
configs/applications/patrol_murdoch_answers.yaml` — its `mission: patrol` derives
launch/patrol_sim.launch (the simulator and the three agents) and copies the layers' parameters
(config/layers_murdoch_params.yaml) from the patrol package (mrta_zenoh/toolchain/
missionfiles.py); both were written by hand before. It holds no code: its layers and evaluators
are the patrol application's, found through their entry points."""
