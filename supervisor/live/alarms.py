"""The supervisor's alarms and the transition history they are written into.

An alarm is (kind, subject) → since. Raising one that is up, or clearing one that is down,
changes nothing (and writes nothing): callers re-derive alarms freely. Every raise is one
WARNING line on the `mrta.supervisor.alarms` logger — a view that shows alarms itself (the
live table, the piped `t=` lines) silences that logger so nothing is said twice."""

from __future__ import annotations

import logging

from mrta_zenoh.untrusted import visible

from .holders import History, StateChange

ALARM_LOG = "mrta.supervisor.alarms"


class Alarms:
    def __init__(self, history: History, quiet: bool = False):
        self.history = history
        self.up: dict[tuple[str, str], float] = {}
        # a replay re-lives old alarms: it must not announce them again
        self._log = logging.getLogger(ALARM_LOG + (".replay" if quiet else ""))
        if quiet:
            self._log.setLevel(logging.ERROR)

    def raise_(self, kind: str, subject: str, now: float, since: float | None = None) -> None:
        """`subject` is shown as given: an id checked by keys.is_id, or a name made visible
        where it came in (Supervisor.on_lockstep, Strangers.token)."""
        if (kind, subject) not in self.up:
            self.up[(kind, subject)] = now if since is None else since
            self.history.add(StateChange(now, "alarm", f"{kind}:{subject}", "", "raised"))
            self._log.warning("alarm: %s %s", kind, subject)

    def clear(self, kind: str, subject: str, now: float) -> None:
        if self.up.pop((kind, subject), None) is not None:
            self.history.add(StateChange(now, "alarm", f"{kind}:{subject}", "raised", "cleared"))

    def set(self, kind: str, subject: str, on: bool, now: float) -> None:
        (self.raise_ if on else self.clear)(kind, subject, now)

    def of_kind(self, kind: str) -> list[str]:
        return [s for k, s in self.up if k == kind]

    def to_json(self) -> list[dict]:
        return [{"kind": k, "subject": s, "since": since}
                for (k, s), since in sorted(self.up.items(), key=lambda kv: kv[1])]


class LockstepAlarms:
    """The lockstep simulator's report (mrta_zenoh.lockstep.protocol.LockstepStatus) as alarms:
    participants it stopped waiting for (`participant_unresponsive`), other clock sources or
    lockstep runs on the bus (`clock_rival`: one source per run, so a second is a
    misconfiguration or a forgery), and StepDones it refused (`lockstep_refused`, raised while
    the count grows from one report to the next). Names from the bus are made visible and at
    most `limit` are taken."""

    def __init__(self, alarms: Alarms, limit: int = 100, name_limit: int = 100):
        self.alarms, self.limit, self.name_limit = alarms, limit, name_limit
        self.dropped = 0  # the simulator's refused StepDones, as last reported

    def report(self, unresponsive: tuple[str, ...], rivals: tuple[str, ...], dropped: int,
               now: float) -> None:
        for kind, subjects in (("participant_unresponsive", unresponsive),
                               ("clock_rival", rivals)):
            names = {visible(n, self.name_limit) for n in subjects[:self.limit]}
            for subject in self.alarms.of_kind(kind):
                if subject not in names:
                    self.alarms.clear(kind, subject, now)
            for name in sorted(names):
                self.alarms.raise_(kind, name, now)
        self.alarms.set("lockstep_refused", "simulator", dropped > self.dropped, now)
        self.dropped = max(self.dropped, dropped)
