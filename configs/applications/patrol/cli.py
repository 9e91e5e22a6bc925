"""`mrta demo`: a thin click wrapper over mrta_patrol.demo.run_demo."""

from __future__ import annotations

from pathlib import Path

import click

from mrta_zenoh.cli.common import finite_float, user_errors

from .demo import ARCHITECTURES, run_demo


def demo_command(architecture: str) -> click.Command:
    """`mrta demo`, with `architecture` as the default of --architecture: the mission each
    application registers under `mrta.missions` (patrol: alliance; patrol_murdoch: murdoch)."""

    @click.command()
    @click.option("--duration", type=finite_float(min=0, min_open=True), default=60.0,
                  show_default=True, help="Simulated seconds of mission.")
    @click.option("--speed", type=finite_float(min=0), default=2.0, show_default=True,
                  help="Simulated seconds per wall second (0: as fast as possible).")
    @click.option("--fail", default="robot2@30", show_default=True, metavar="ROBOT@SECONDS|none",
                  help="SIGKILL this robot's agent at this simulated time.")
    @click.option("--output", type=click.Path(file_okay=False, path_type=Path),
                  default=Path("demo-output"), show_default=True,
                  help="Folder for the recording, pictures and summary.json.")
    @click.option("--seed", type=int, default=0, show_default=True,
                  help="The run's master seed (each robot derives its own stream).")
    @click.option("--live/--no-live", default=None,
                  help="Show the live supervisor view (default: when the output is a terminal).")
    @click.option("--lockstep/--no-lockstep", default=True, show_default=True,
                  help="The simulator waits for every agent at each step: the same seed gives the "
                       "same run whatever the machine's load.")
    @click.option("--foxglove", "foxglove_port", type=click.IntRange(0, 65535), is_flag=False,
                  flag_value=8765, default=None, metavar="[PORT]",
                  help="Also serve the run live to Foxglove / Lichtblick (ws://127.0.0.1:8765).")
    @click.option("--architecture", type=click.Choice(sorted(ARCHITECTURES)), default=architecture,
                  show_default=True, help="Run the mission under ALLIANCE (application patrol) or "
                                          "MURDOCH (application patrol_murdoch).")
    def demo(duration: float, speed: float, fail: str, output: Path, seed: int,
             live: bool | None, lockstep: bool, foxglove_port: int | None, architecture: str) -> None:
        """The patrol application end to end: simulator, agents and supervisor, then a summary."""
        with user_errors():
            run_demo(duration=duration, speed=speed, fail=fail, output=output, seed=seed, live=live,
                     lockstep=lockstep, foxglove_port=foxglove_port, architecture=architecture)

    return demo


demo = demo_command("alliance")
murdoch_mission = demo_command("murdoch")
