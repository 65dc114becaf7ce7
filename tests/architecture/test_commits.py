"""Commit messages since issue 33 have a short subject and a body (docs/DEVELOPING.md).

The rule is checked by ``tools/check_commit_messages.py`` on the commits after its
``SINCE`` (the history before had one long subject line per commit). The history check
skips when there is no git history reaching ``SINCE``: no ``.git`` (an unpacked
archive), a shallow clone cut after it, or a history in which it is not an ancestor.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tools"))

import check_commit_messages as ccm  # noqa: E402


def test_a_long_subject_is_refused():
    message = "x" * 73 + "\n\nbody\n"
    assert ccm.message_problems(message, merge=False) == ["subject of 73 characters (at most 72)"]
    assert ccm.message_problems("x" * 72 + "\n\nbody\n", merge=False) == []


def test_a_commit_without_body_is_refused_but_a_merge_may_have_none():
    assert ccm.message_problems("fix the reader\n", merge=False) == ["no body saying why"]
    assert ccm.message_problems("fix the reader\n\n\n", merge=False) == ["no body saying why"]
    assert ccm.message_problems("Merge branch 'x'\n", merge=True) == []


def test_the_body_is_separated_by_a_blank_line():
    problems = ccm.message_problems("subject\nbody at once\n", merge=False)
    assert "no blank line after the subject" in problems


def test_a_good_message_passes():
    message = "io: read CR-only ZephIR files\n\nThe logger of site X writes CR.\n"
    assert ccm.message_problems(message, merge=False) == []


def _git(cwd: Path, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run(["git", "-C", str(cwd), *args], capture_output=True, text=True)


def _history_reaches(revision: str) -> bool:
    """Whether this checkout's history holds ``revision`` as an ancestor of HEAD."""
    if shutil.which("git") is None or not (ROOT / ".git").exists():
        return False
    if _git(ROOT, "cat-file", "-e", f"{revision}^{{commit}}").returncode != 0:
        return False
    return _git(ROOT, "merge-base", "--is-ancestor", revision, "HEAD").returncode == 0


@pytest.mark.skipif(shutil.which("git") is None, reason="no git")
def test_the_tool_reads_a_history_and_names_the_bad_commit(tmp_path):
    """End to end on a small repository: one good commit, one with a long subject."""
    assert _git(tmp_path, "init", "-q").returncode == 0
    for n, message in enumerate(["start\n\nthe first file", "y" * 80 + "\n\nwhy"]):
        (tmp_path / f"f{n}").write_text(str(n))
        _git(tmp_path, "add", f"f{n}")
        done = _git(
            tmp_path,
            "-c",
            "user.name=t",
            "-c",
            "user.email=t@example.org",
            "commit",
            "-q",
            "-m",
            message,
        )
        assert done.returncode == 0, done.stderr
    found = ccm.commits("HEAD", cwd=str(tmp_path))
    assert [c.parents for c in found] == [1, 0]
    assert found[0].message.startswith("y" * 80)
    assert ccm.message_problems(found[1].message, merge=False) == []
    assert ccm.message_problems(found[0].message, merge=False) == [
        "subject of 80 characters (at most 72)"
    ]


def test_a_revision_range_that_git_cannot_read_is_one_line(capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # not a repository
    assert ccm.main(["no-such-commit..HEAD"]) == 2
    out = capsys.readouterr().out
    assert out.startswith("check_commit_messages: cannot read no-such-commit..HEAD")
    assert "Traceback" not in out


def test_the_history_since_the_rule_keeps_it():
    if not _history_reaches(ccm.SINCE):
        pytest.skip(f"no git history reaching {ccm.SINCE[:10]} (shallow clone or no .git)")
    found = ccm.commits(f"{ccm.SINCE}..HEAD", cwd=str(ROOT))
    bad = {
        f"{c.sha[:10]} {c.message.splitlines()[0][:50]}": problems
        for c in found
        if (problems := ccm.message_problems(c.message, merge=c.parents > 1))
    }
    assert bad == {}, "commit messages breaking the rule of docs/DEVELOPING.md"
