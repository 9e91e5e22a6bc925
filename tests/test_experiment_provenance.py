"""results.csv's `code` column (supervisor/experiment/provenance.py): every row names the code
that made it — a checkout's commit, `+dirty` when its code differs from that commit (its rows
do not), a distribution's version otherwise, all read from files without running git — and a folder whose older rows have no such column
resumes, its old rows blank, the new ones named, and the report says which made what."""

from __future__ import annotations

import csv
import subprocess
from pathlib import Path

import pytest

from mrta_supervisor.experiment import api as experiment
from mrta_supervisor.experiment import provenance
from mrta_supervisor.experiment.provenance import CODE_COLUMN, DIRTY, code_revision
from tests.test_experiment_runs import exp_file, missions, rows  # noqa: F401 (a fixture)


def git(cwd: Path, *args: str) -> str:
    return subprocess.run(["git", "-c", "user.name=t", "-c", "user.email=t@t", *args],
                          cwd=cwd, check=True, capture_output=True, text=True).stdout.strip()


def make_checkout(root: Path, index_version: int) -> Path:
    """A git checkout with the project's layout (a package and docs), one commit, its index
    in the given format."""
    (root / "mrta_zenoh" / "sub").mkdir(parents=True)
    (root / "docs" / "study").mkdir(parents=True)
    (root / "mrta_zenoh" / "core.py").write_text("A = 1\n")
    for n in range(12):  # paths of many lengths: the index pads (v2, v3) or shares (v4) them
        (root / "mrta_zenoh" / "sub" / f"m{'x' * n}.py").write_text(f"N = {n}\n")
    (root / "docs" / "study" / "results.csv").write_text("run\n")
    git(root, "init", "-q")
    git(root, "add", ".")
    git(root, "update-index", "--index-version", str(index_version))
    git(root, "commit", "-q", "-m", "one")
    return root


@pytest.mark.multiprocess  # git makes the checkouts; the code read never runs it: the CI case
@pytest.mark.parametrize("index_version", [2, 4])
def test_a_checkout_is_named_by_its_commit_and_dirty_only_for_its_code(tmp_path,
                                                                       index_version):
    checkout = make_checkout(tmp_path / "checkout", index_version)
    head = git(checkout, "rev-parse", "HEAD")
    assert provenance.checkout_of(checkout / "mrta_zenoh") == checkout.resolve()
    assert provenance.revision_of(checkout) == head[:12]
    # rows written into the checkout's own docs/study (run.sh's default) are not code
    (checkout / "docs" / "study" / "results.csv").write_text("run\n0\n")
    assert provenance.revision_of(checkout) == head[:12]
    (checkout / "mrta_zenoh" / "core.py").write_text("A = 2\n")
    assert provenance.revision_of(checkout) == head[:12] + DIRTY
    git(checkout, "commit", "-q", "-am", "two")
    assert provenance.revision_of(checkout) == git(checkout, "rev-parse", "HEAD")[:12]
    (checkout / "mrta_zenoh" / "new.py").write_text("B = 1\n")  # a new module is code too
    assert provenance.revision_of(checkout).endswith(DIRTY)
    (checkout / "mrta_zenoh" / "new.py").unlink()
    (checkout / "mrta_zenoh" / "sub" / "mxxx.py").unlink()  # so is one gone
    assert provenance.revision_of(checkout).endswith(DIRTY)
    # a worktree (a `.git` file naming its folder), as every engineer's here
    git(checkout, "worktree", "add", "-q", "-b", "other", str(tmp_path / "wt"))
    assert provenance.checkout_of(tmp_path / "wt" / "mrta_zenoh") == (tmp_path / "wt").resolve()
    assert provenance.revision_of(tmp_path / "wt") == git(checkout, "rev-parse", "HEAD")[:12]
    git(checkout, "pack-refs", "--all")  # its branch's commit from packed-refs
    assert provenance.revision_of(tmp_path / "wt") == git(checkout, "rev-parse", "HEAD")[:12]


def test_a_package_outside_a_checkout_is_named_by_its_distribution(tmp_path, monkeypatch):
    (tmp_path / "site" / "mrta_zenoh").mkdir(parents=True)
    assert provenance.checkout_of(tmp_path / "site" / "mrta_zenoh") is None
    (tmp_path / "site" / ".git").write_text("not a link\n")  # unreadable git data: not a commit
    assert provenance.revision_of(tmp_path / "site") is None
    monkeypatch.setattr(provenance.mrta_zenoh, "__file__",
                        str(tmp_path / "site" / "mrta_zenoh" / "__init__.py"))
    provenance.code_revision.cache_clear()
    try:
        assert provenance.code_revision().startswith("mrta-zenoh ")
    finally:
        provenance.code_revision.cache_clear()


def test_every_row_names_its_code_and_older_rows_resume_blank(tmp_path, missions):
    out = tmp_path / "o"
    experiment.run_experiment(file=exp_file(tmp_path), output=out, jobs=1, plots=False)
    table = rows(out)
    assert {r[CODE_COLUMN] for r in table} == {code_revision()}
    assert f"Code (`{CODE_COLUMN}` column): `{code_revision()}`." in \
        (out / "summary.md").read_text()
    # the folder as an older version left it: no `code` column, and two runs still to do
    old = [{k: v for k, v in r.items() if k != CODE_COLUMN} for r in table[:2]]
    with (out / "results.csv").open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(old[0]))
        w.writeheader()
        w.writerows(old)
    missions.clear()
    experiment.run_experiment(file=exp_file(tmp_path), output=out, jobs=1, plots=False)
    assert sorted(i for i, _, _ in missions) == [2, 3]  # only the missing runs
    resumed = rows(out)
    assert [r[CODE_COLUMN] for r in resumed] == ["", "", code_revision(), code_revision()]
    assert "2 runs from before rows named their code" in (out / "summary.md").read_text()
    # and the report's cells are not split by it: a bookkeeping column, not a parameter
    cells = {r["cell"] for r in csv.DictReader((out / "cells.csv").open())}
    assert cells == {"fail=none", "fail=robot2@5"}
