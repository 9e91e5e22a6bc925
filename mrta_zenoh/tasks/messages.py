"""The wire of tasks at run time (package docstring). Every message is small and bounded: a
task's fields travel as a JSON object text of at most MAX_FIELDS bytes, checked by the intake."""

from __future__ import annotations

import enum

from ..messages import Finite, Header, Message, message

REQUEST = "tasks/request"        # tasks/request/<submitter>: a submitter's requests
ANSWER = "tasks/answer"          # tasks/answer/<submitter>: the intake's answers to it
CHANGE = "tasks/change"          # what entered the run, at the instant it entered
HISTORY = "tasks/history"        # queried: the run's task set so far, as changes (a late view)
INTAKE = "tasks"                 # the intake's process name (participant, refusal tally)
MAX_FIELDS = 4096                # bytes of a task's fields (JSON) an intake reads
MAX_LISTING = 256 * 1024         # bytes of a listing answered at once


class Op(str, enum.Enum):
    SUBMIT = "submit"
    CANCEL = "cancel"
    REPRIORITIZE = "reprioritize"
    LIST = "list"

    def __str__(self) -> str:
        return self.value


class Outcome(str, enum.Enum):
    ACCEPTED = "accepted"        # it entered the run (`at`: the simulated instant)
    REFUSED = "refused"          # not taken (`reason` says why); nothing changed
    UNKNOWN = "unknown"          # no such task (cancel, reprioritize)
    LISTED = "listed"            # `listing` holds the tasks (list)

    def __str__(self) -> str:
        return self.value


def request_key(submitter: str) -> str:
    return f"{REQUEST}/{submitter}"


def answer_key(submitter: str) -> str:
    return f"{ANSWER}/{submitter}"


@message("task_msgs/Request")
class Request(Message):
    """A submitter's request (header.frame_id: the submitter, its key's last chunk too);
    `request`: the submitter's own id for it, echoed in the answer."""

    header: Header
    request: str
    op: str
    task_id: str = ""
    fields: str = ""             # submit: the task's fields, a JSON object
    priority: int = 0            # submit, reprioritize: higher is more urgent


@message("task_msgs/Answer")
class Answer(Message):
    header: Header
    request: str
    outcome: str
    task_id: str = ""
    reason: str = ""
    at: Finite = 0.0             # accepted: the simulated instant it entered the run
    listing: str = ""            # list: a JSON array of the tasks submitted and their state


@message("task_msgs/Change")
class Change(Message):
    """What entered the run at header.stamp (a step boundary): a task arrived (`fields`,
    `priority`), was cancelled, or was given a new priority. Every process of the run that
    takes tasks at run time takes it then."""

    header: Header
    op: str
    task_id: str
    fields: str = ""
    priority: int = 0
    submitter: str = ""
