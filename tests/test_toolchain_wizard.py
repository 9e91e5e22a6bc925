"""`mrta app new` never writes what `mrta app validate` refuses: the files
are read by the architecture before any is written; the wizard asks again for the answers behind
a refused file, an answers file is refused at its line; empty mandatory answers are told why;
layer sections no plugin of the application reads are neither asked for nor written."""

from __future__ import annotations

import yaml
import pytest
from click.testing import CliRunner

from mrta_zenoh.cli.main import cli
from mrta_zenoh.toolchain.xmlio import load_rqt_mrta
from tests.harness.helpers import ALLIANCE_ARCH, CONFIGS

PATROL_ANSWERS = CONFIGS / "applications" / "patrol_answers.yaml"


def run(*args, input=None):
    return CliRunner().invoke(cli, list(map(str, args)), input=input)


def answers(tmp_path, change) -> tuple:
    data = yaml.safe_load(PATROL_ANSWERS.read_text())
    change(data)
    f = tmp_path / "answers.yaml"
    f.write_text(yaml.safe_dump(data, sort_keys=False))
    return f, f.read_text().splitlines()


def line_of(lines: list[str], text: str, after: str = "") -> int:
    """The 1-based line holding `text` (the first after the line holding `after`)."""
    start = next(i for i, x in enumerate(lines) if after in x) if after else 0
    return next(i for i, x in enumerate(lines) if i >= start and text in x) + 1


def assert_refused(res, out, *fragments):
    assert res.exit_code == 2, res.output
    (line,) = res.output.strip().splitlines()
    for f in fragments:
        assert f in line, line
    assert not out.exists() or not any(out.iterdir())


def test_answers_with_a_task_the_tasks_file_lacks_are_refused_at_the_tasks_file(tmp_path):
    def drop_report(d):
        d["configs"]["tasks_alliance_params"]["tasks"] = [
            t for t in d["configs"]["tasks_alliance_params"]["tasks"] if t["id"] != "report"]
    f, lines = answers(tmp_path, drop_report)
    res = run("app", "new", "--answers", f, "--output", tmp_path / "out")
    assert_refused(res, tmp_path / "out",
                   f"{f}:{line_of(lines, 'tasks_alliance_params:')}: the package would not "
                   "load: config/robot1_alliance_params.yaml: 'task_id': behaviour set for task "
                   "'report'", "the robots were given wander, border_protection, report")


def test_answers_with_a_misspelt_task_in_the_tasks_file_say_which_ids_are_right(tmp_path):
    """The architecture's own hint proposes the misspelling ('reprot'); the robots' tasks —
    the application's — say which spelling is right."""
    def misspell(d):
        d["configs"]["tasks_alliance_params"]["tasks"][2]["id"] = "reprot"
    f, _ = answers(tmp_path, misspell)
    res = run("app", "new", "--answers", f, "--output", tmp_path / "out")
    assert_refused(res, tmp_path / "out", "the tasks file has border_protection, reprot, wander",
                   "the robots were given wander, border_protection, report")


@pytest.mark.slow
def test_answers_with_an_unknown_sensor_plugin_are_refused_at_its_line(tmp_path):
    def typo(d):
        d["configs"]["alliance_params"]["robot2"]["sensors"] = [
            {"plugin_name": "alliance/odometri", "topic_name": "odom"},
            {"plugin_name": "alliance/point_cloud", "topic_name": "sonar"}]
    f, lines = answers(tmp_path, typo)
    res = run("app", "new", "--answers", f, "--output", tmp_path / "out")
    assert_refused(res, tmp_path / "out",
                   f"{f}:{line_of(lines, 'alliance/odometri', after='robot2:')}: the package "
                   "would not load: config/robot2_alliance_params.yaml:",
                   "unknown sensor plugin 'alliance/odometri' (did you mean 'alliance/odometry'?)")


def test_the_shipped_answers_still_make_the_shipped_package(tmp_path):
    """All three patrol tasks' layers read every section: nothing is left out."""
    res = run("app", "new", "--answers", PATROL_ANSWERS, "--output", tmp_path)
    assert res.exit_code == 0, res.output
    shipped = CONFIGS / "applications" / "patrol" / "config" / "layers_alliance_params.yaml"
    assert (tmp_path / "patrol/config/layers_alliance_params.yaml").read_bytes() == \
        shipped.read_bytes()


def test_the_wizard_ends_with_next_steps_that_work_as_printed(tmp_path, monkeypatch):
    """It ended with 'wrote N files' and no next step (issue 51, the newcomer's list): the
    launch line it prints starts every robot's agent (dry run), found on the path it names."""
    import shlex
    data = yaml.safe_load(PATROL_ANSWERS.read_text())
    data["package"] = "mypatrol"
    f = tmp_path / "answers.yaml"
    f.write_text(yaml.safe_dump(data, sort_keys=False))
    out = tmp_path / "my apps"
    res = run("app", "new", "--answers", f, "--output", out)
    assert res.exit_code == 0, res.output
    said = res.output.split("next:\n", 1)[1].splitlines()
    launch = shlex.split(next(x for x in said if " mrta launch " in x).split("#")[0])
    env, argv = launch[0].split("=", 1), launch[3:]
    assert env == ["MRTA_PACKAGE_PATH", str(out)] and launch[1:3] == ["mrta", "launch"]
    assert argv == ["mypatrol", "mypatrol.launch"]
    monkeypatch.setenv(*env)
    dry = run("launch", *argv, "--dry-run")
    assert dry.exit_code == 0, dry.output
    assert [x.split("]")[0] for x in dry.output.splitlines()] == \
        ["[robot1/alliance", "[robot2/alliance", "[robot3/alliance"]
    assert "mrta demo" in said[-1] and "mission" in said[-1]


# ------------------------------------------------------------------ the wizard in the terminal
WANDER_ONLY = [
    "mypkg", "", "My App", "", "", "Ana", "ana@example.org", "", "", "",  # an empty name: told why
    "single-task", "", "", "",                                         # ALLIANCE
    "robot1", "wander", "",                                            # one robot, one task
    # robot1_alliance_params: an empty mandatory name, then a sensor plugin misspelt
    "", "Robot 1", "", "", "", "", "1", "alliance/odometri", "odom", "", "",
    "60", "20", "30", "60", "2", "", "1", "odom",
    # tasks_alliance_params: one entry per task given above, its id filled in
    "Wander", "1", "patrol/wander",
    # refused: robot1's file is asked for again, the earlier answers offered as defaults
    "", "", "", "", "", "", "alliance/odometry", "", "", "",
    "", "", "", "", "", "", "", "",
    # layers_alliance_params: only Wander's three parameters are asked for
    "", "", "",
    "y",
]


@pytest.mark.slow
def test_the_wizard_asks_again_for_a_refused_file_and_only_for_the_layers_read(tmp_path):
    res = run("app", "new", "--output", tmp_path, input="\n".join(WANDER_ONLY) + "\n")
    assert res.exit_code == 0, res.output
    assert "Error: the name cannot be empty" in res.output
    assert "Error: name is mandatory: give a value" in res.output
    assert ("Error: the package would not load: config/robot1_alliance_params.yaml:10: unknown "
            "sensor plugin 'alliance/odometri'") in res.output
    assert "[alliance/odometri]" in res.output  # the earlier answer, offered again
    # no section a plugin of a wander-only robot does not read
    template = load_rqt_mrta(ALLIANCE_ARCH / "rqt_mrta.xml").config("layers_alliance_params")
    assert {g.name for g in template.children} == {"Wander", "BorderProtection", "Report"}
    assert "BorderProtection" not in res.output and "Report/" not in res.output
    pkg = tmp_path / "mypkg"
    layers = yaml.safe_load((pkg / "config" / "layers_alliance_params.yaml").read_text())
    assert list(layers) == ["Wander"]
    robot = yaml.safe_load((pkg / "config" / "robot1_alliance_params.yaml").read_text())
    assert robot["sensors"]["sensor0"]["plugin_name"] == "alliance/odometry"
    assert robot["name"] == "Robot 1"
    assert run("app", "validate", pkg).exit_code == 0


def test_fast_rate_is_told_per_tick_as_the_runtime_adds_it():
    arch = load_rqt_mrta(ALLIANCE_ARCH / "rqt_mrta.xml")

    def find(children, name):
        for c in children:
            if c.name == name:
                return c
            found = find(getattr(c, "children", []), name)
            if found is not None:
                return found
        return None

    tip = find(arch.config("alliance_params").children, "fast_rate").tool_tip
    assert "per high-level tick" in tip and "per second" not in tip


def test_an_answers_file_of_aliases_cannot_make_a_million_sensors(tmp_path):
    """Aliases are allowed in answers files (to share a block), so a short file can name one
    sensor a great many times: arrays are bounded, and the error line is one short line."""
    text = PATROL_ANSWERS.read_text()
    block = ("      sensors: &sensors\n"
             "        - {plugin_name: alliance/odometry, topic_name: odom}\n"
             "        - {plugin_name: alliance/point_cloud, topic_name: sonar}\n")
    assert block in text
    many = ("      sensors: &sensors [&s {plugin_name: alliance/odometry, topic_name: odom}"
            + ", *s" * 1000 + "]\n")
    text = text.replace(block, many, 1)
    f = tmp_path / "answers.yaml"
    f.write_text(text)
    res = run("app", "new", "--answers", f, "--output", tmp_path / "out")
    assert_refused(res, tmp_path / "out", "robot1/sensors/sensor: 1,001 entries, more than 1,000")
    assert len(res.output) < 300


def test_a_task_the_tasks_file_lacks_has_the_wizard_ask_the_tasks_file_again(tmp_path):
    """The wizard asks again for the answers of the file a refusal names: a robot's task the
    tasks file lacks is the tasks file's to fix — the wizard re-asked robot1's ~25 questions
    forever, never the tasks file (issue 51, the newcomer's list)."""
    from mrta_zenoh.toolchain.checks import PackageRefused, check_package_files
    from mrta_zenoh.toolchain.generator import build_application, load_answers
    from mrta_zenoh.toolchain.registry import Registry

    def drop_report(d):
        d["configs"]["tasks_alliance_params"]["tasks"] = [
            t for t in d["configs"]["tasks_alliance_params"]["tasks"] if t["id"] != "report"]
    f, _ = answers(tmp_path, drop_report)
    a, _ = load_answers(f)
    arch_pkg, arch = Registry().architecture(a.architecture)
    app, files = build_application(arch_pkg, arch, a)
    with pytest.raises(PackageRefused) as refused:
        check_package_files(files, app)
    assert refused.value.generated == "config/tasks_alliance_params.yaml"
    assert "config/robot1_alliance_params.yaml" in str(refused.value)  # where it was found


class Quiet:
    """A prompter that shows nothing: a test's own answers its `ask`."""

    def step(self, title):
        pass

    def section(self, title):
        pass

    def say(self, text):
        pass


class TakeDefaults(Quiet):
    """A prompter answering every question with its default, else a word, else a number;
    `heard` sees each question and its default."""

    def heard(self, question, default):
        pass

    def ask(self, question, check, default=None, show_default=True):
        from mrta_zenoh.toolchain.wizard import InvalidAnswer
        self.heard(question, default)
        for text in (default, "x", "1"):
            try:
                return check(text or "")
            except InvalidAnswer:
                pass
        raise AssertionError(question)


def test_an_architecture_typed_at_a_filter_prompt_is_told_what_the_prompt_takes():
    """Typing `alliance` at the first filter prompt said "--robots 'alliance'", a flag of
    `mrta arch list` no prompt has (issue 51, the newcomer's list)."""
    from mrta_zenoh.toolchain.registry import Registry
    from mrta_zenoh.toolchain.wizard import InvalidAnswer, collect

    said = []

    class Script(Quiet):
        answers = iter(["mypkg", "My app", "", "", "Me", "me@example.com", "", "", "",
                        "alliance"])

        def ask(self, question, check, default=None, show_default=True):
            text = next(self.answers)
            try:
                return check(text if text or default is None else default)
            except InvalidAnswer as exc:
                said.append(str(exc))
                raise

    with pytest.raises(InvalidAnswer):
        collect(Registry(), Script())
    assert said == ["'alliance' is no robots type: give ST/MT, or nothing for any (an "
                    "architecture is chosen by name next)"]


def test_the_tasks_file_takes_the_task_ids_given_in_step_3_without_asking_them_again():
    """Task ids were asked twice: in step 3 and again, with how many, in the tasks file (issue
    51, the newcomer's list). The tasks file now has one entry per task given, ids filled in."""
    from mrta_zenoh.toolchain.generator import Answers
    from mrta_zenoh.toolchain.wizard import _ask_config

    asked = []

    class Defaults(TakeDefaults):
        def heard(self, question, default):
            asked.append(question)

    arch = load_rqt_mrta(ALLIANCE_ARCH / "rqt_mrta.xml")
    a = Answers(package="p", name="P", architecture="alliance", configs={},
                robots={"robot1": ["wander", "report"], "robot2": ["report", "clean"]})
    _ask_config(Defaults(), a, arch, "tasks_alliance_params", {})
    assert [t["id"] for t in a.configs["tasks_alliance_params"]["tasks"]["task"]] == \
        ["wander", "report", "clean"]
    assert not [q for q in asked if q.startswith("tasks_alliance_params/tasks: how many")
                or q.split(" [")[0].endswith("/id")], asked
    assert "tasks_alliance_params/tasks/task2/name [string] — Task display name." in asked


def test_alliances_motivation_parameters_offer_defaults():
    """Six ALLIANCE parameters were mandatory with no default (≈ 45 prompts to type for two
    robots and two tasks; issue 51, the newcomer's list): a behaviour set's expected duration,
    threshold, yielding and giving-up delays and fast rate now offer one, in their ranges and
    with yielding before giving up (as the robot file's check wants)."""
    from mrta_zenoh.toolchain.generator import Answers
    from mrta_zenoh.toolchain.wizard import _ask_config

    offered = {}

    class Defaults(TakeDefaults):
        def heard(self, question, default):
            offered[question.split(" [")[0].rsplit("/", 1)[-1]] = default

    arch = load_rqt_mrta(ALLIANCE_ARCH / "rqt_mrta.xml")
    a = Answers(package="p", name="P", architecture="alliance", configs={},
                robots={"robot1": ["wander"]})
    _ask_config(Defaults(), a, arch, arch.config_id, {})
    defaults = {k: offered[k] for k in ("task_expected_duration", "threshold", "yielding_delay",
                                        "giving_up_delay", "fast_rate")}
    assert all(v is not None for v in defaults.values()), defaults
    assert float(defaults["yielding_delay"]) <= float(defaults["giving_up_delay"])


def test_an_interrupted_wizard_keeps_its_answers_and_resume_asks_only_the_rest(tmp_path):
    """Ctrl-C (here: the end of input, click's Abort too) lost every answer (issue 51, the
    newcomer's list): the answers given are written beside the output, and `--resume` gives
    them again — an answer no longer accepted is asked for."""
    from mrta_zenoh.cli.toolchain import RESUME_FILE
    from mrta_zenoh.toolchain.wizard import load_transcript
    first = run("app", "new", "--output", tmp_path,
                input="my_app\nMy App\n\n\nMe\nnot-an-email\nme@x.org\n")
    assert first.exit_code == 1 and "Aborted!" in first.output
    kept = tmp_path / RESUME_FILE
    assert f"6 answers kept in {kept}" in first.output
    given = load_transcript(kept)
    assert given["Package name (lower case, e.g. my_mission)"] == ["my_app"]
    assert given["Maintainer e-mail"] == ["me@x.org"]  # the accepted one, not the refused
    assert given["Version"] == ["1.0.0"]  # a default taken is an answer too
    again = run("app", "new", "--output", tmp_path, "--resume", kept, input="\n\n")
    assert "Package name (lower case, e.g. my_mission): my_app" in again.output
    assert "Maintainer e-mail: me@x.org" in again.output
    assert again.output.count("Maintainer e-mail") == 1  # not asked again
    assert "8 answers kept" in again.output  # and kept again, with the two new ones
    kept.write_text(kept.read_text().replace("answer: my_app", "answer: My-App"))
    third = run("app", "new", "--output", tmp_path, "--resume", kept, input="fixed\n")
    assert third.exit_code == 1  # My-App is refused: asked, and "fixed" typed
    assert load_transcript(kept)["Package name (lower case, e.g. my_mission)"] == ["fixed"]


def test_a_resume_file_that_is_no_transcript_is_refused_naming_its_line(tmp_path):
    f = tmp_path / "a.yaml"
    f.write_text("- question: Version\n  answer: 1.0.0\n- question: Licence\n")
    res = run("app", "new", "--resume", f)
    assert res.exit_code == 2 and "a.yaml:3:" in res.output, res.output
