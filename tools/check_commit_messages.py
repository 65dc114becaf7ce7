"""Check that commit messages can be skimmed: a short subject, a blank line, a body.

The rule (docs/DEVELOPING.md, issue 33):

- the subject (first line) is at most 72 characters;
- a commit that is not a merge has a body, separated from the subject by one blank line;
- a merge commit may be its subject alone.

Usage::

    python3 tools/check_commit_messages.py [REVISION_RANGE]

``REVISION_RANGE`` defaults to ``SINCE..HEAD``, ``SINCE`` being the last commit before
the rule. Exit status 1 lists every commit that breaks the rule, 2 says that git could
not read the range, 0 otherwise.
"""

from __future__ import annotations

import subprocess
import sys
from dataclasses import dataclass

#: The last commit not held to the rule: main just before the commit that added this
#: tool (issue 33). Every commit after it, on any branch merged since, is checked.
SINCE = "7c6f71f0b5b38535d3468e12841b7bbb5dcf4a17"
MAX_SUBJECT = 72
_SEP = "\x1e"


@dataclass(frozen=True)
class Commit:
    """One commit's hash, parent count and full message."""

    sha: str
    parents: int
    message: str


def message_problems(message: str, *, merge: bool) -> list[str]:
    """Return what is wrong with one commit message ([] when nothing)."""
    lines = message.rstrip("\n").split("\n")
    subject = lines[0]
    problems = []
    if not subject.strip():
        problems.append("empty subject")
    if len(subject) > MAX_SUBJECT:
        problems.append(f"subject of {len(subject)} characters (at most {MAX_SUBJECT})")
    if len(lines) > 1 and lines[1].strip():
        problems.append("no blank line after the subject")
    body = [line for line in lines[2:] if line.strip()]
    if not merge and not body:
        problems.append("no body saying why")
    return problems


def commits(revision_range: str, cwd: str | None = None) -> list[Commit]:
    """Read the commits of ``revision_range`` from git in ``cwd`` (newest first)."""
    out = subprocess.run(
        ["git", "log", f"--format=%H %P%n%B{_SEP}", revision_range],
        capture_output=True,
        text=True,
        check=True,
        cwd=cwd,
    ).stdout
    found = []
    for record in out.split(_SEP):
        record = record.lstrip("\n")
        if not record.strip():
            continue
        head, _, message = record.partition("\n")
        sha, *parents = head.split()
        found.append(Commit(sha, len(parents), message))
    return found


def main(argv: list[str]) -> int:
    """Check the commits of ``argv[0]`` (default ``SINCE..HEAD``); exit status 0, 1 or 2."""
    revision_range = argv[0] if argv else f"{SINCE}..HEAD"
    try:
        found = commits(revision_range)
    except (OSError, subprocess.CalledProcessError) as err:
        detail = getattr(err, "stderr", "") or str(err)
        print(f"check_commit_messages: cannot read {revision_range}: {detail.strip()}")
        return 2
    bad = 0
    for commit in found:
        problems = message_problems(commit.message, merge=commit.parents > 1)
        if problems:
            bad += 1
            subject = commit.message.split("\n", 1)[0]
            print(f"{commit.sha[:10]} {subject[:60]!r}: {'; '.join(problems)}")
    print(f"{len(found)} commits in {revision_range}, {bad} breaking the rule")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
