"""``docs/architecture.md`` stays true (issue 33): its layer table is the enforced one,
and every module, folder and test it names exists.

The layer table sits between the markers ``<!-- layers: begin`` and ``<!-- layers: end``,
one row per package (``| layer | `cwproc.x` | what it may do |``); its rows, grouped by
layer in order, must equal :data:`test_layers.LAYERS`. Every ``cwproc/...`` or
``tests/...`` path of the page must exist (a glob must match), and every dotted
``cwproc.x.y`` name must be a module, or a name defined in the longest module it starts
with. The *before* picture must be what ``tools/layer_picture.py --rev`` prints for its
commit, when the history holds it.
"""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DOC = ROOT / "docs" / "architecture.md"
sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(ROOT / "tools"))

import layer_picture  # noqa: E402
from test_layers import LAYERS  # noqa: E402

ROW = re.compile(r"^\|\s*(\d+)\s*\|\s*`([\w.]+)`\s*\|")
PATH = re.compile(r"(?<![\w/.])((?:cwproc|tests|docs|tools)/[\w/.*-]*[\w*/])")
DOTTED = re.compile(r"`(cwproc(?:\.\w+)*)")


def layer_rows(text: str) -> tuple[tuple[str, ...], ...]:
    """The packages of the layer table, grouped by layer in order of the rows."""
    inside = text.split("<!-- layers: begin", 1)[1].split("<!-- layers: end", 1)[0]
    groups: dict[int, list[str]] = {}
    for line in inside.splitlines():
        if match := ROW.match(line):
            groups.setdefault(int(match.group(1)), []).append(match.group(2))
    assert sorted(groups) == list(range(len(groups))), f"layers {sorted(groups)} not 0..n"
    return tuple(tuple(groups[k]) for k in sorted(groups))


def missing_paths(text: str, root: Path = ROOT) -> list[str]:
    """Paths of ``text`` under cwproc/, tests/, docs/ or tools/ that do not exist."""
    out = []
    for path in sorted(set(PATH.findall(text))):
        found = list(root.glob(path.rstrip("/"))) if "*" in path else [root / path]
        if not found or not all(p.exists() for p in found):
            out.append(path)
    return out


def _module_file(name: str, root: Path) -> Path | None:
    base = root.joinpath(*name.split("."))
    for candidate in (base / "__init__.py", base.with_suffix(".py")):
        if candidate.exists():
            return candidate
    return base if base.is_dir() else None


def unknown_names(text: str, root: Path = ROOT) -> list[str]:
    """Dotted ``cwproc...`` names of ``text`` that are neither a module nor defined in one."""
    out = []
    for name in sorted(set(DOTTED.findall(text))):
        parts = name.split(".")
        for n in range(len(parts), 0, -1):
            source = _module_file(".".join(parts[:n]), root)
            if source is not None:
                break
        rest = parts[n:]
        if source is None or len(rest) > 2:
            out.append(name)
        elif rest and not (
            source.is_file() and re.search(rf"\b{rest[0]}\b", source.read_text(encoding="utf-8"))
        ):
            out.append(name)
    return out


def test_the_layer_table_is_the_enforced_one():
    assert layer_rows(DOC.read_text(encoding="utf-8")) == LAYERS


def test_every_path_the_page_names_exists():
    bad = missing_paths(DOC.read_text(encoding="utf-8"))
    assert not bad, "docs/architecture.md names paths that do not exist: " + ", ".join(bad)


def test_every_dotted_name_is_a_module_or_defined_in_one():
    bad = unknown_names(DOC.read_text(encoding="utf-8"))
    assert not bad, "docs/architecture.md names what cwproc does not have: " + ", ".join(bad)


def test_the_checks_see_a_wrong_page(tmp_path):
    (tmp_path / "cwproc" / "io").mkdir(parents=True)
    (tmp_path / "cwproc" / "io" / "__init__.py").write_text("def read():\n    pass\n")
    page = "`cwproc/io/__init__.py` `cwproc/io/gone.py` `cwproc.io.read` `cwproc.io.write`"
    assert missing_paths(page, tmp_path) == ["cwproc/io/gone.py"]
    assert unknown_names(page, tmp_path) == ["cwproc.io.write"]
    table = "<!-- layers: begin -->\n| 0 | `cwproc.errors` | x |\n| 1 | `cwproc.io` | y |\n"
    assert layer_rows(table + "<!-- layers: end -->") == (("cwproc.errors",), ("cwproc.io",))


def _history_has(rev: str) -> bool:
    if shutil.which("git") is None or not (ROOT / ".git").exists():
        return False
    done = subprocess.run(
        ["git", "-C", str(ROOT), "cat-file", "-e", f"{rev}^{{commit}}"], capture_output=True
    )
    return done.returncode == 0


def test_the_before_picture_is_that_of_its_commit():
    text = DOC.read_text(encoding="utf-8")
    rev = re.search(r"layer_picture\.py --rev (\w+)", text).group(1)
    if not _history_has(rev):
        pytest.skip(f"no git history reaching {rev} (shallow clone or no .git)")
    before = layer_picture.picture(layer_picture.revision_sources(rev), 10, None)
    assert before in text, f"the before picture of docs/architecture.md is not that of {rev}"
