"""murdoch_msgs: MURDOCH's auction protocol (Gerkey & Matarić 2002, §III) on the bus.

A task's life: an auctioneer publishes an `Announcement` (task, required resources, bid
window); every idle robot able to do it answers with a `Bid` (its utility); when the window
closes the auctioneer publishes an `Award` to the highest bidder; the winner then renews a
`Claim` (its lease) every renewal period while it works, and publishes a `Release` when it gives
the task back. A task's auctioneer that sees a contract last longer than the task's
progress_timeout without the task being done publishes a `Revoke`: every robot then treats the
task as unheld (and ignores that contract's claims), and the holder gives it back. `Claim` is
what the supervisor watches (`header/frame_id`, `task_id`): who is busy with what, with the same
field names as ALLIANCE's broadcasts.
"""

from __future__ import annotations

from mrta_zenoh.messages import Finite, Header, Message, message


@message("murdoch_msgs/Announcement")
class Announcement(Message):
    """`header/frame_id` is the auctioneer; (auctioneer, auction) names the auction."""

    header: Header
    auction: int
    task_id: str
    resources: tuple[str, ...] = ()
    bid_window: Finite = 0.5


@message("murdoch_msgs/Bid")
class Bid(Message):
    header: Header
    auctioneer: str
    auction: int
    task_id: str
    utility: Finite


@message("murdoch_msgs/Award")
class Award(Message):
    header: Header
    auction: int
    task_id: str
    winner: str
    utility: Finite


@message("murdoch_msgs/Claim")
class Claim(Message):
    """"I hold `task_id` since `since` (my clock); renewed every renewal period, valid for
    `lease` seconds after it was heard." Two holders of one task keep the earlier claim."""

    header: Header
    task_id: str
    since: Finite
    lease: Finite


@message("murdoch_msgs/Release")
class Release(Message):
    header: Header
    task_id: str
    reason: str


@message("murdoch_msgs/Revoke")
class Revoke(Message):
    """"`holder`'s contract for `task_id`, the one it claims `since`, is over": its auctioneer
    saw no progress (the task not done) within the task's progress_timeout."""

    header: Header
    task_id: str
    holder: str
    since: Finite
    reason: str
