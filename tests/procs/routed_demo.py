"""`mrta demo ARGS…` with the run's router from the first robot on (mission.ROUTER_FROM = 1):
the router topology on a team small enough for a test."""

import sys

from mrta_supervisor.mission import runner as mission
from mrta_zenoh.cli.main import cli

mission.ROUTER_FROM = 1
sys.argv[0] = "mrta"
cli()
