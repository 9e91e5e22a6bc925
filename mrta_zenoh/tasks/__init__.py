"""Tasks at run time (issue 50; docs/tasks.md): people and systems submit, cancel and
reprioritise tasks while a mission runs.

* `messages.py` — the wire: a submitter's `Request` on `tasks/request/<submitter>`, the intake's
  `Answer` on `tasks/answer/<submitter>`, and what entered the run, `Change` on `tasks/change`
  (an arrival, a cancellation, a new priority), stamped with the simulated instant it entered.
* `intake.py` — the intake's rules, pure and on an injected clock: a request checked (size, id,
  the application's own task type through its instance kind), bounded per submitter (rate and
  pending, so a flood is counted and dropped, never queued without bound), and released at the
  next step boundary.
* `server.py` — `mrta task serve`: the intake as a process of the run (a lockstep participant,
  so every process takes a change at the same simulated instant); it also replays the changes
  an instance's `submitted` schedule holds (a run repeated from its summary).
* `api.py` — the client side the `mrta task` verbs wrap: submit one or many, cancel,
  reprioritise, list.

The core knows no application: a task's fields are the application's (checked by its instance
kind's `admit`), carried as a JSON object.
"""
