"""Print the layer picture of ``cwproc``: modules and lines per package, the largest functions.

The picture of ``docs/architecture.md`` ("before and after", issue 33) is this script's
output::

    python3 tools/layer_picture.py              # the working tree
    python3 tools/layer_picture.py --rev 3230ca5  # a commit of the history (read by git)
    python3 tools/layer_picture.py --top 15     # more of the largest functions

A package is a folder of ``cwproc/`` (``stages/epsilon`` is its own row); the modules
directly in ``cwproc/`` form the row ``(top level)``. For the working tree each row also
names its layer, the index in ``tests/architecture/test_layers.LAYERS`` (0 at the
bottom). Lines are physical lines of the source; a function's size counts from its
``def`` to its last line, as ``tests/architecture/test_sizes.py`` does.
"""

from __future__ import annotations

import argparse
import ast
import subprocess
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TOP_LEVEL = "(top level)"


@dataclass(frozen=True)
class Function:
    """One function or method: where it is and how many lines it spans."""

    path: str
    line: int
    name: str
    lines: int


def tree_sources() -> dict[str, str]:
    """``{path: text}`` of every ``cwproc/**/*.py`` of the working tree."""
    return {
        str(p.relative_to(ROOT)): p.read_text(encoding="utf-8")
        for p in sorted((ROOT / "cwproc").rglob("*.py"))
    }


def revision_sources(rev: str) -> dict[str, str]:
    """``{path: text}`` of every ``cwproc/**/*.py`` of the commit ``rev`` (via git)."""

    def git(*args: str) -> str:
        return subprocess.run(
            ["git", "-C", str(ROOT), *args], capture_output=True, text=True, check=True
        ).stdout

    names = git("ls-tree", "-r", "--name-only", rev, "cwproc").split()
    return {n: git("show", f"{rev}:{n}") for n in names if n.endswith(".py")}


def package_of(path: str) -> str:
    """``cwproc/stages/epsilon/errors.py`` -> ``stages/epsilon``; top-level modules."""
    parts = Path(path).parts[1:-1]
    return "/".join(parts) if parts else TOP_LEVEL


def packages(sources: dict[str, str]) -> dict[str, tuple[int, int]]:
    """``{package: (modules, lines)}`` in the order of the paths."""
    out: dict[str, tuple[int, int]] = {}
    for path, text in sorted(sources.items()):
        modules, lines = out.get(package_of(path), (0, 0))
        out[package_of(path)] = (modules + 1, lines + len(text.splitlines()))
    return out


def functions(sources: dict[str, str]) -> list[Function]:
    """Every function and method, largest first (then by path and line)."""
    found = []
    for path, text in sources.items():
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                n = node.end_lineno - node.lineno + 1
                found.append(Function(path.removeprefix("cwproc/"), node.lineno, node.name, n))
    return sorted(found, key=lambda f: (-f.lines, f.path, f.line))


def layer_function() -> Callable[[str], int] | None:
    """``test_layers.layer_of`` of this checkout, None when the test is absent."""
    tests = ROOT / "tests" / "architecture"
    if not (tests / "test_layers.py").exists():
        return None
    sys.path.insert(0, str(tests))
    try:
        import test_layers
    finally:
        sys.path.remove(str(tests))
    return test_layers.layer_of


def picture(sources: dict[str, str], top: int, layer_of: Callable[[str], int] | None) -> str:
    """Markdown: modules and lines per package (and per layer), the ``top`` largest functions."""
    rows = packages(sources)
    with_layer = layer_of is not None
    head = (
        "| package | layer | modules | lines |" if with_layer else "| package | modules | lines |"
    )
    out = [head, "|" + " --- |" * (head.count("|") - 1)]
    for package, (modules, lines) in rows.items():
        cells = [f"`{package}`" if package != TOP_LEVEL else package]
        if with_layer:
            cells.append(_layers_of(package, sources, layer_of))
        cells += [str(modules), f"{lines:,}"]
        out.append("| " + " | ".join(cells) + " |")
    total_modules = sum(m for m, _ in rows.values())
    total_lines = sum(n for _, n in rows.values())
    cells = ["**total**"] + ([""] if with_layer else []) + [str(total_modules), f"{total_lines:,}"]
    out.append("| " + " | ".join(cells) + " |")
    if with_layer:
        out += ["", *_per_layer(sources, layer_of)]
    sizes = sorted((len(t.splitlines()), p.removeprefix("cwproc/")) for p, t in sources.items())
    lengths = [f.lines for f in functions(sources)]
    out += [
        "",
        f"Largest module: `{sizes[-1][1]}` ({sizes[-1][0]} lines); modules over 600 lines: "
        f"{sum(n > 600 for n, _ in sizes)}, over 760: {sum(n > 760 for n, _ in sizes)}. "
        f"Functions over 80 lines: {sum(n > 80 for n in lengths)}, over 100: "
        f"{sum(n > 100 for n in lengths)}.",
    ]
    out += ["", "| lines | function |", "| --- | --- |"]
    out += [f"| {f.lines} | `{f.path}:{f.line}` `{f.name}` |" for f in functions(sources)[:top]]
    return "\n".join(out)


def module_name(path: str) -> str:
    """``cwproc/io/halo.py`` -> ``cwproc.io.halo``; a package's ``__init__`` is the package."""
    parts = list(Path(path).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _per_layer(sources: dict[str, str], layer_of: Callable[[str], int]) -> list[str]:
    """A Markdown table of the modules and lines of each layer."""
    counts: dict[int, list[int]] = {}
    for path, text in sources.items():
        entry = counts.setdefault(layer_of(module_name(path)), [0, 0])
        entry[0] += 1
        entry[1] += len(text.splitlines())
    out = ["| layer | modules | lines |", "| --- | --- | --- |"]
    return out + [f"| {k} | {m} | {n:,} |" for k, (m, n) in sorted(counts.items())]


def _layers_of(package: str, sources: dict[str, str], layer_of: Callable[[str], int]) -> str:
    """The layer(s) of a package's modules (the top level spans several)."""
    names = {module_name(p) for p in sources if package_of(p) == package}
    found = sorted({layer_of(n) for n in names})
    return ", ".join(str(k) for k in found)


def main(argv: list[str] | None = None) -> int:
    """Print the picture of the working tree or of ``--rev``; 2 when git cannot read it."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rev", help="a commit to measure instead of the working tree")
    parser.add_argument("--top", type=int, default=10, help="largest functions to list")
    args = parser.parse_args(argv)
    if args.rev:
        try:
            sources = revision_sources(args.rev)
        except (OSError, subprocess.CalledProcessError) as err:
            detail = (getattr(err, "stderr", "") or str(err)).strip()
            print(f"layer_picture: cannot read {args.rev}: {detail}")
            return 2
        print(picture(sources, args.top, None))
    else:
        print(picture(tree_sources(), args.top, layer_function()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
