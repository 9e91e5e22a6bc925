"""Lockstep simulation time: the simulator advances only when every participant has finished
its work for the current simulated time (Gazebo's lockstep; ROS `use_sim_time` with a
synchronous clock). A run's outcome then depends on the seed only, not on how busy the machine
is or how fast the simulator is allowed to go.

The protocol (docs/architecture.md, "lockstep"):

* A participant (an agent on `--sim-time`) holds the liveliness token
  `@mrta/lockstep/participant/<id>`; the simulator waits for exactly those. An agent host
  (robot_agent/runtime/agent_host.py: several robots' agents in one process) is one participant
  that answers for each of its robots, saying so first with a token
  `@mrta/lockstep/speaks/<id>/<robot>` per robot: its claims may be under those robots' names.
  A token gone (the process died) is no longer waited for. An `@` key is matched by no wildcard, so observers
  (`echo '**'`, the recorder) neither see lockstep traffic nor take part in it.
* After each physics step — sensor data published first, on the same link — the simulator
  publishes `Step(stamp, step, counts, keys, base, table_digest)` reliably on
  `@mrta/lockstep/step`: cumulative counts per key, by index in the run's key table
  (`KeyTable`), of which it carries only the keys new since the previous step — the whole
  table to a newcomer, to a participant silent for REPORT_AFTER (one that missed keys), and
  every REPORT_AFTER while one is given up; past MAX_KEYS keys a new table, sent whole.
* A participant's time moves to `stamp` only once it has received every sample the other
  participants had published before their last acknowledgement (the counts, for the keys it
  subscribes to). That is what makes a broadcast from robot A, sent while
  A handled step k, reach robot B before B handles step k+1, whatever the network's scheduling.
* When the participant has nothing more to do at that time — its main loop would wait for a
  later time — it publishes `StepDone(participant, stamp, sent, next)` on
  `@mrta/lockstep/done/<id>`: its commands of that step went out before it, on the same link,
  and `next` is the time it waits for. The simulator stops only at steps where some
  participant has something due (an agent at 10 Hz: every fifth 20 ms step), so lockstep costs
  one round trip per participant tick, not per physics step.
* The simulator steps again once every participant is done and it has taken their commands
  of that step into account (counted as for the participants). A participant silent for
  `REPORT_AFTER` (2.5 s: below the 3 s Zenoh lease, so a stopped process is reported before its
  token expires) is reported in the log and still waited for while it holds its participant
  token — a slow participant on a busy machine must not change what the run does. One silent
  for `timeout` wall seconds (30 s by default) with its token alive is given up (a log line
  and `lockstep/status`, which the supervisor shows as an alarm) until it answers again; the
  status counts give-ups and forgiven claims, and a mission's summary calls such a run inexact.
  Silent means neither an answer nor a work beat: a participant whose loop is computing (its
  loop thread's CPU time grows, `participant.LoopCpu`) says so every WORK_BEAT with a StepDone
  marked `working` and is waited for, up to WORK_LIMIT timeouts — a long decision on a busy
  machine is not a hang; a stuck loop uses no CPU time and says nothing.

Trust (docs/security.md, "Lockstep and the clock"). Exact checks — they hold against anybody
who cannot declare our tokens (a secured fleet) and against blind forgers on an open bus:
* a Step counts only if its `run` holds `@mrta/lockstep/barrier/<run>`; a participant follows
  one run at a time, and another run is taken only once the first one's token is gone (a second
  lockstep simulator is reported, not followed);
* a step counts only as the next one in sequence, or as the same step again; whatever
  contradicts what a participant took (a step out of sequence, another under a number it took,
  a table it cannot read) makes it ask the barrier for the current step with the whole table,
  which it takes whatever its number (`sequence`): one forged step costs a request's round trip;
  a step behind the participant's time moves no time, it is answered at once;
* a participant's claims count only under its own name, within caps on keys and their length
  and while the run's table has room; over a cap its claims are dropped, not the Steps
  (`ledger`);
* a StepDone counts only from a name that holds its participant token, under its own key, for
  this run, for a step already published (never "done" in advance); its `next` is clamped to
  `NEXT_HORIZON` seconds ahead, so no claim can excuse a participant for long;
* a run that ends (its barrier token is gone) restarts the participant's counts, sent and
  received, and a new run its time;
* a member whose process has ended, as the run's runner says through a file (`ended`), is not
  waited for past ENDED_AFTER whatever token lives under its name (Zenoh shows one token per
  key however many sessions declare it: a forger's outlives the member's process).
Heuristics — plausibility against an attacker on an open bus who copies run ids and names:
* a step stops at or before a participant's own `next` plus one physics step (`STEP_SLACK`):
  a later one is taken only as far as wall time allows since the participant was last heard
  (a `StepBudget` at the run's announced speed, mrta_zenoh.clock.run_rate) — that is how a
  participant that was stopped, and given up, rejoins the current step;
* counts: a claim more than `MAX_IN_FLIGHT` samples beyond what arrived is dropped at once; a
  smaller one that is not met within `count_wait(timeout)` is forgiven (`Books`: the samples were
  lost, e.g. while a stopped peer's link was down) — counted and logged, never waited for again;
  a later, lower claim for the same key withdraws a forgiveness (legitimate counts only grow
  within a run, so the forgiven one was forged); once a claimant's claims were forgiven, its
  unmet claims are forgiven without waiting for FORGIVE_WINDOW — one pause per claimant per
  window, however its claims move.
The barrier also re-publishes the step it waits on when a participant (re)appears, so a
resumed or late participant answers at once instead of after the timeout, and stops every
REPORT_AFTER to send the whole table while any participant is given up.

The package, by concern. Each name is imported from the module that defines it (`from
mrta_zenoh.lockstep.protocol import STEP`): the package itself exports nothing, so an agent
loads the participant's modules only, the supervisor and the access-control generator the
protocol only (tests/process/test_lockstep.py says so):
* `protocol` — keys, messages (Step, StepDone, LockstepStatus) and limits;
* `table` — the run's key table and a step's claims by index (KeyTable, Claims);
* `books` — what a process received of what was claimed, less what it forgave (Books);
* `sequence` — which steps a participant believes, and when it asks for the whole table;
* `participant` — a participant's clock (LockstepClock);
* `ledger` — each participant's last answer and claims, and their caps;
* `barrier` — the simulator's side (Barrier);
* `ended` — which of a run's processes have ended, from its runner to the barrier (EndedWatch).
"""
