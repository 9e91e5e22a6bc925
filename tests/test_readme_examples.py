"""The README's examples are what the commands print: every output sample in the
README that starts with `$ mrta …` is run and compared, line by line, with what it prints.

In a sample, `…` on a line of its own skips any number of lines, and `…` inside a line
matches any text there; the wall time (`in 32 s`) is the machine's and is not compared.
A demo sample is run at `--speed 0` when its command gives no speed: in lockstep the same seed
gives the same lines at any speed (the README says so; this checks it too), only faster; its
header must then show the default speed, as the command would have run."""

from __future__ import annotations

import re
import shlex

import pytest

from tests.harness.helpers import ROOT

README = ROOT / "README.md"
WALL = re.compile(r"(at speed )(\S+)( in )\d+( s)")


def samples() -> list[tuple[list[str], list[str]]]:
    """(argv after `mrta`, expected lines) for each ``` block opening with `$ mrta`."""
    out, block = [], None
    for line in README.read_text().splitlines():
        if line.startswith("```"):
            if block is not None and block and block[0].startswith("$ mrta "):
                out.append((shlex.split(block[0])[2:], block[1:]))
            block = [] if block is None else None
        elif block is not None:
            block.append(line)
    return out


def default_speed() -> float:
    from mrta_supervisor.mission.cli import demo
    return next(p.default for p in demo.params if p.name == "speed")


def matches(expected: list[str], got: list[str], speed_given: bool) -> None:
    """`expected` (with `…` lines skipping anything) in order within `got`."""
    default = f"{default_speed():.1f}"

    def same(e: str, g: str) -> bool:
        # run at --speed 0 when the README's command gives none: it would have run at the
        # default speed, which the README must show
        e = WALL.sub(r"\1\2\3N\4", e)
        g = WALL.sub(r"\1\2\3N\4" if speed_given else rf"\g<1>{default}\3N\4", g)
        return re.fullmatch(".*".join(map(re.escape, e.split("…"))), g) is not None

    i = 0
    skipping = False
    for e in expected:
        if e == "…":
            skipping = True
            continue
        while i < len(got) and not same(e, got[i]):
            assert skipping, f"README line {e!r}\nbut the command printed {got[i]!r}\n{got}"
            i += 1
        assert i < len(got), f"README line {e!r} is not in what the command printed:\n{got}"
        i += 1
        skipping = False


def test_the_readme_has_its_samples():
    commands = [argv[:3] for argv, _ in samples()]
    assert ["demo"] in commands and ["demo", "--architecture", "murdoch"] in commands


def test_the_comparison_catches_what_the_readme_got_wrong():
    """A wrong MURDOCH sample: `mrta demo --architecture murdoch` (speed 2.0) shown with
    `speed max`; and a line the command wraps in two."""
    got = ["Patrol mission (MURDOCH): 60 s simulated at speed max in 8 s",
           "  robot2 killed at 30.0 s; robot3 took over after 2.30 s (within the bound 2.80 s)"]
    with pytest.raises(AssertionError):
        matches(["Patrol mission (MURDOCH): 60 s simulated at speed max in 5 s", "…"], got,
                speed_given=False)
    matches(["Patrol mission (MURDOCH): 60 s simulated at speed 2.0 in 5 s", "…"], got, False)
    matches(["…", "  robot2 killed at 30.0 s; robot3 took over after 2.30 s (within …)"], got,
            True)
    with pytest.raises(AssertionError):
        matches(["…", "  robot2 killed at 30.0 s; robot3 took over after 2.30 s", "  (within …"],
                got, True)


@pytest.mark.multiprocess
@pytest.mark.timeout(240)
@pytest.mark.parametrize("argv,expected", [
    # the CI tier runs the first sample (`mrta demo`, what a newcomer runs first: the format of
    # every demo's lines), the slow tier the rest (≈ 15 CPU-s each; MURDOCH's run from the wheel
    # is .ci/wheel's demo)
    pytest.param(argv, expected, id=" ".join(argv), marks=() if i == 0 else pytest.mark.slow)
    for i, (argv, expected) in enumerate(samples())])
def test_a_readme_sample_is_what_its_command_prints(argv, expected, children, tmp_path):
    out = tmp_path / "demo-output"
    speed_given = "--speed" in argv
    run = [*argv, *([] if speed_given else ["--speed", "0"])]
    if argv[0] == "demo":
        run += ["--no-live", "--output", out]
    child = children.mrta(*run, name="readme")
    assert child.wait(200) == 0, child.tail(30)
    got = [line.replace(str(out), "demo-output") for line in child.stdout]
    matches(expected, got, speed_given)


@pytest.mark.multiprocess
@pytest.mark.timeout(120)
def test_the_separate_terminals_simulator_says_what_the_readme_says(children, tokens):
    text = README.read_text()
    command = next(line for line in text.splitlines() if line.startswith("mrta sim --world patrol"))
    said = re.search(r"the simulator logs `([^`]*)`", text).group(1)
    sim = children.mrta(*shlex.split(command)[1:], name="sim")
    line = sim.wait_stderr(lambda x: "ready:" in x, 60)
    assert line.split(": ", 1)[1] == said, line
    # the agents' commands, as written (C=… set first), and what each logs when ready
    folder = re.search(r"^C=(\S+)$", text, flags=re.M).group(1)
    agent = next(line for line in text.splitlines() if line.startswith("mrta agent robot1 "))
    argv = shlex.split(agent.replace("$C", str(ROOT / folder)))[1:]
    robot1 = children.mrta(*argv, name="robot1")
    said = re.search(r"each agent logs `([^`]*)`", text).group(1).replace("robotN", "robot1")
    robot1.wait_stderr(lambda x: x.endswith(said), 60)


@pytest.mark.multiprocess
@pytest.mark.slow  # four patrol runs; the CI tier runs experiments in test_experiment_resume_multiprocess
@pytest.mark.timeout(300)
def test_the_experiment_table_is_what_its_file_gives(children, tmp_path):
    """The README's table came from another file than the one shown above it (robot2@15
    under a file with robot2@30)."""
    text = README.read_text()
    yaml_text = re.search(r"```yaml\n(# small\.yaml\n.*?)```", text, flags=re.S).group(1)
    table = re.search(r"gives, in `summary\.md`[^\n]*\n\n((?:\|[^\n]*\n)+)", text).group(1)
    (tmp_path / "small.yaml").write_text(yaml_text)
    exp = children.mrta("experiment", tmp_path / "small.yaml", "--output", tmp_path / "small",
                        "--jobs", "2", name="experiment")
    assert exp.wait(280) == 0, exp.tail(20)
    assert table in (tmp_path / "small" / "summary.md").read_text()
