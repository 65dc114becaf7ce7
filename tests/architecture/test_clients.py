"""The command line is a thin client: it runs the pipeline, never a stage (issue 16).

``cwproc/cli/*`` may import :mod:`cwproc.pipeline` (the one chain of stages,
``run_unit``), the configuration and :mod:`cwproc.io` (to check arguments), and the
clients whose commands it offers (``sim``, ``batch``, ``plots``); an import of
``cwproc.stages`` (also inside a function, also ``from cwproc import stages``) would be a
second copy of the chain and fails here. The source is read, nothing is imported.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

CLI = Path(__file__).resolve().parents[2] / "cwproc" / "cli"

#: what the command line may not import: the retrieval stages
FORBIDDEN = "cwproc.stages"


def stage_imports(source: str, package: str = "cwproc.cli") -> list[str]:
    """``line: module`` of every import of :data:`FORBIDDEN` in ``source``, at any depth."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:  # relative: from the cli package upwards
                parts = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(parts + ([node.module] if node.module else []))
            targets = [base] + [f"{base}.{alias.name}" for alias in node.names]
        else:
            continue
        hits = [t for t in targets if t == FORBIDDEN or t.startswith(FORBIDDEN + ".")]
        found.extend(f"{node.lineno}: {t}" for t in hits[:1])
    return found


def test_no_cli_module_imports_a_stage():
    bad = [
        f"{path.relative_to(CLI.parent.parent)}:{line}"
        for path in sorted(CLI.rglob("*.py"))
        for line in stage_imports(path.read_text(encoding="utf-8"))
    ]
    assert not bad, "cli modules that run stages themselves (use cwproc.pipeline):\n" + "\n".join(
        bad
    )


@pytest.mark.parametrize(
    "source",
    [
        "from cwproc.stages.stare import stare_mask\n",
        "def f():\n    from cwproc.stages import sonic_sf\n",
        "import cwproc.stages.qc as qc\n",
        "from cwproc import stages\n",
        "from ..stages import vad\n",
    ],
)
def test_the_check_sees_a_stage_import(source):
    """The checker itself: every spelling of a stage import is found."""
    assert len(stage_imports(source)) == 1


@pytest.mark.parametrize(
    "source",
    [
        "from cwproc.pipeline import run_unit\n",
        "from cwproc.io import detect_format\n",
        "import cwproc.stagesque\n",
    ],
)
def test_the_check_lets_the_pipeline_through(source):
    assert stage_imports(source) == []
