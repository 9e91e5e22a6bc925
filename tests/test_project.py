"""The README's fresh-machine commands are what CI runs."""

from tests.harness.helpers import ROOT


def _code_lines(text):
    return [line.strip() for line in text.splitlines()
            if line.strip().startswith("python3 -m venv")]


def test_ci_runs_exactly_the_readme_test_command():
    readme = _code_lines((ROOT / "README.md").read_text())
    ci = _code_lines((ROOT / ".ci" / "run").read_text())
    assert len(readme) == 2, "README opens with the two fresh-machine commands"
    assert ci == [readme[1]]
    assert "pytest" in readme[1]
