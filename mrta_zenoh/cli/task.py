"""`mrta task submit | cancel | reprioritize | list | serve`: thin click verbs over
mrta_zenoh.tasks (api.py for the first four, server.py for `serve`), docs/tasks.md.

Each answers with what happened, one line per request — `t9 accepted at 12.30 s`, `t9 refused:
malformed: …`, `t9 unknown: no such task` — and exits 2 when a request was not accepted (bad
input: the line says why), 1 when no intake answered."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import click

from ..bus import BusOptions
from ..errors import ConfigError, MrtaRuntimeError
from ..node import Node
from ..tasks.api import Submitter, TaskRequest
from ..tasks.intake import Limits
from ..tasks.messages import Op, Outcome
from ..tasks.requests import requests_from_file, task_fields
from .common import bus_options, finite_float, plural

SUBMITTER_ROLE = "submitter"


@click.group()
def task() -> None:
    """Tasks at run time: submit, cancel, reprioritise and list a running mission's tasks."""


def _common(f):
    f = click.option("--as", "name", default="operator", show_default=True, metavar="NAME",
                     help="Who submits (its requests go on tasks/request/NAME; on a secured "
                          "fleet, the submitter whose certificate this process holds).")(f)
    f = click.option("--timeout", type=finite_float(min=0, min_open=True), default=30.0,
                     show_default=True, help="Wall seconds to wait for the intake and its "
                                             "answers (it answers at the run's next step).")(f)
    return bus_options(f)


def _ask(bus_options: BusOptions, name: str, requests: list[TaskRequest],
         timeout: float) -> list:
    with Node(bus_options, SUBMITTER_ROLE, name=name) as node, \
            Submitter(node.bus, name) as submitter:
        submitter.wait_for_intake(timeout)
        answers = submitter.ask(requests, timeout)
    missing = sum(a is None for a in answers)
    if missing:
        raise MrtaRuntimeError(f"{plural(missing, 'request')} of {len(answers)} got no answer "
                               f"within {timeout:g} s (the intake answers at the run's next "
                               f"step, which may wait for a robot still deciding: it may yet "
                               f"enter — `mrta task list` says; --timeout waits longer)")
    return answers


def _say(requests: list[TaskRequest], answers: list) -> None:
    refused = []
    for r, a in zip(requests, answers):
        if a.outcome == Outcome.ACCEPTED:
            line = f"{r.task_id} accepted at {a.at:.2f} s"
        else:
            line = f"{r.task_id} {a.outcome}: {a.reason}"
            refused.append(line)
        click.echo(line)
    if refused:
        more = f" ({len(refused)} of {len(requests)} not accepted)" if len(requests) > 1 else ""
        raise ConfigError(refused[0] + more)


@task.command()
@click.argument("task_id", required=False)
@click.option("--set", "sets", multiple=True, metavar="FIELD=VALUE",
              help="A field of the task (the application's: delivery's position=[1.5,-2], "
                   "service=4, capability=lift, reward, earliest, due); VALUE is YAML. "
                   "Repeatable.")
@click.option("--json", "as_json", metavar="OBJECT",
              help="The task's fields as one JSON object, or an Open-RMF task_request (delivery: "
                   "its dropoff place; compose/go_to_place: its place; a place is \"X,Y\").")
@click.option("--priority", type=int, default=0, show_default=True,
              help="Higher is more urgent.")
@click.option("--file", "file", type=click.Path(exists=True, dir_okay=False, path_type=Path),
              help="Many tasks: a YAML or JSON file, id → fields (with an optional priority "
                   "each), or a list of objects with an `id`.")
@_common
def submit(task_id: str | None, sets: tuple[str, ...], as_json: str | None, priority: int,
           file: Path | None, name: str, timeout: float, bus_options: BusOptions) -> None:
    """Submit TASK_ID (its fields as --set or --json), or every task of --file."""
    if file is not None:
        if task_id or sets or as_json:
            raise click.UsageError("--file takes no TASK_ID, --set or --json")
        requests = requests_from_file(file)
    else:
        if not task_id:
            raise click.UsageError("give TASK_ID (or --file)")
        fields, stated = task_fields(sets, as_json)
        requests = [TaskRequest(Op.SUBMIT, task_id, fields,
                                stated if stated is not None and priority == 0 else priority)]
    _say(requests, _ask(bus_options, name, requests, timeout))


@task.command()
@click.argument("task_id")
@_common
def cancel(task_id: str, name: str, timeout: float, bus_options: BusOptions) -> None:
    """Cancel TASK_ID: withdrawn from whoever holds it, never served after."""
    requests = [TaskRequest(Op.CANCEL, task_id)]
    _say(requests, _ask(bus_options, name, requests, timeout))


@task.command()
@click.argument("task_id")
@click.argument("priority", type=int)
@_common
def reprioritize(task_id: str, priority: int, name: str, timeout: float,
                 bus_options: BusOptions) -> None:
    """Give TASK_ID priority PRIORITY (higher is more urgent)."""
    requests = [TaskRequest(Op.REPRIORITIZE, task_id, priority=priority)]
    _say(requests, _ask(bus_options, name, requests, timeout))


@task.command(name="list")
@click.option("--json", "as_json", is_flag=True, help="One JSON array.")
@_common
def list_tasks(as_json: bool, name: str, timeout: float, bus_options: BusOptions) -> None:
    """The tasks submitted to the running mission so far, and their state."""
    (answer,) = _ask(bus_options, name, [TaskRequest(Op.LIST)], timeout)
    tasks: list[dict[str, Any]] = json.loads(answer.listing or "[]")
    if as_json:
        click.echo(json.dumps(tasks))
        return
    if not tasks:  # said, not left blank: an empty answer reads as a verb that did nothing
        click.echo("no task submitted to this run yet (its instance's own tasks are not "
                   "listed: `mrta supervise` shows every task)")
    for t in tasks:
        state = f"cancelled at {t['cancelled_at']:.2f} s" if t.get("cancelled_at") is not None \
            else "in the run"
        click.echo(f"{t['id']}  entered {t['at']:.2f} s  priority {t.get('priority', 0)}  "
                   f"{state}  ({t.get('submitter', '')})")


@task.command()
@click.option("--instance", required=True, type=click.Path(dir_okay=False, path_type=Path),
              help="The run's instance (its tasks may be cancelled; its `submitted` replays).")
@click.option("--application", metavar="APP", help="The application whose instance kind reads it.")
@click.option("--sim-time", is_flag=True,
              help="A lockstep participant on the simulator's clock (what a mission runs).")
@click.option("--duration", type=finite_float(min=0, min_open=True),
              help="Stop after this many seconds (of its clock).")
@click.option("--rate", type=finite_float(min=0, min_open=True), default=Limits.rate,
              show_default=True, help="Requests a wall second each submitter may send.")
@click.option("--burst", type=click.IntRange(min=1), default=Limits.burst, show_default=True,
              help="Requests a submitter may send at once.")
@click.option("--closed", metavar="REASON", default="",
              help="Refuse every submission with this reason (the run's architecture serves no "
                   "task submitted at run time); cancellations are still taken.")
@bus_options
def serve(instance: Path, application: str | None, sim_time: bool, duration: float | None,
          rate: float, burst: int, closed: str, bus_options: BusOptions) -> None:
    """The run's task intake (the mission runner starts it; by hand beside `mrta sim`)."""
    from ..tasks.server import ServeOptions, serve as run
    run(ServeOptions(instance, application, bus_options, sim_time, duration,
                     Limits(rate=rate, burst=burst), closed))
