"""SSI's and CBBA's declared stalls in a real run's summary (issue 51.2): `mrta demo` in lockstep
on the default delivery instance, robot4 stalled at 3 s. Its teammates count it out
`progress_timeout` (10 s) after its last progress, its tasks go to the others — and the
summary names the stall, who declared it and when (`decisions.declared`), as it did only for
central's dispatcher before."""

from __future__ import annotations

import pytest

from tests.process.test_central_multiprocess import assert_every_task_done_once, run_demo

pytestmark = [pytest.mark.multiprocess, pytest.mark.slow]


@pytest.mark.timeout(300)
@pytest.mark.parametrize("architecture,deciders", [
    ("ssi", {"robot1"}),                                   # the auctioneer
    ("cbba", {"robot1", "robot2", "robot3", "robot5"})])  # every teammate
def test_a_stall_ssi_or_cbba_declared_is_named_in_the_summary(children, tmp_path, architecture,
                                                               deciders):
    s = run_demo(children, tmp_path / "out", "90", "--architecture", architecture,
                 "--fail", "stall:robot4@3")
    assert_every_task_done_once(s)
    declared = s["decisions"]["declared"]
    assert {d["by"] for d in declared if d["robot"] == "robot4"} == deciders, declared
    for d in declared:
        assert (d["robot"], d["reason"], d["until"]) == ("robot4", "stalled", None), declared
        assert 3.0 + 10.0 <= d["at"] <= 3.0 + 10.0 + 3.0, declared  # its timeout, reports lag
