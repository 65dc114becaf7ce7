"""Write a Jupyter notebook (``.ipynb``) of a percent-format script, executed.

``docs/examples/*.py`` are notebooks in jupytext's percent format (cells opened by
``# %%``, markdown cells by ``# %% [markdown]``): they run as scripts and are executed by
the tests. This tool writes the same cells as an ``.ipynb`` beside them, with each code
cell's printed output, so that the notebook reads with its results on a web page or in
Jupyter without jupytext. It needs only the standard library (nbformat 4 is plain JSON)::

    python3 tools/percent_to_ipynb.py docs/examples/stages.py

The cells are run in order in one namespace, in a temporary folder (the files the
example writes are not kept). ``tests/test_examples.py`` checks that the notebook's
cells are the script's.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import sys
import tempfile
from pathlib import Path


def percent_cells(text: str) -> list[tuple[str, str]]:
    """``[(kind, source)]`` of a percent-format script; kind is 'code' or 'markdown'."""
    cells: list[tuple[str, list[str]]] = []
    for line in text.splitlines():
        if line.startswith("# %%"):
            cells.append(("markdown" if "[markdown]" in line else "code", []))
        elif cells:
            cells[-1][1].append(line)
    out = []
    for kind, lines in cells:
        if kind == "markdown":
            lines = [line[2:] if line.startswith("# ") else line.lstrip("#") for line in lines]
        source = "\n".join(lines).strip("\n")
        if source:
            out.append((kind, source))
    return out


def _lines(source: str) -> list[str]:
    parts = source.split("\n")
    return [p + "\n" for p in parts[:-1]] + [parts[-1]]


def notebook(script: Path, *, execute: bool = True) -> dict:
    """The nbformat-4 notebook of ``script``, its code cells run in order when
    ``execute`` (``__file__`` is the script's path, the working folder a temporary one)."""
    script = script.resolve()
    namespace: dict = {"__name__": "__main__", "__file__": str(script)}
    cells = []
    here = os.getcwd()
    with tempfile.TemporaryDirectory() as work:
        os.chdir(work)
        try:
            for count, (kind, source) in enumerate(percent_cells(script.read_text()), 1):
                if kind == "markdown":
                    cell = {"cell_type": "markdown", "id": f"cell-{count}", "metadata": {}}
                    cells.append(cell | {"source": _lines(source)})
                    continue
                outputs = []
                if execute:
                    printed = io.StringIO()
                    with contextlib.redirect_stdout(printed):
                        exec(compile(source, f"{script.name} cell {count}", "exec"), namespace)
                    if printed.getvalue():
                        text = printed.getvalue()
                        outputs = [
                            {"output_type": "stream", "name": "stdout", "text": _lines(text)}
                        ]
                cells.append(
                    {
                        "cell_type": "code",
                        "id": f"cell-{count}",
                        "execution_count": count if execute else None,
                        "metadata": {},
                        "outputs": outputs,
                        "source": _lines(source),
                    }
                )
        finally:
            os.chdir(here)
    kernel = {"display_name": "Python 3", "language": "python", "name": "python3"}
    return {
        "cells": cells,
        "metadata": {"kernelspec": kernel, "language_info": {"name": "python"}},
        "nbformat": 4,
        "nbformat_minor": 5,
    }


def main(argv: list[str]) -> int:
    if not argv:
        print(__doc__)
        return 2
    for name in argv:
        script = Path(name)
        target = script.with_suffix(".ipynb")
        target.write_text(json.dumps(notebook(script), indent=1, ensure_ascii=False) + "\n")
        print(f"wrote {target}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
