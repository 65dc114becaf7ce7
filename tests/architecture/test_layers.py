"""The core only points down (issue 16): an import that runs up a layer fails here.

Every ``import`` / ``from ... import`` statement in ``cwproc`` is checked, including the
ones inside functions, by reading the source (nothing is imported). Layers, bottom up:

0. foundation: ``cwproc._version``, ``cwproc.errors``, ``cwproc.references``,
   ``cwproc.progress``
1. ``cwproc.physics``: numpy and scipy only (no xarray, no configuration)
2. ``cwproc.io``: files <-> canonical datasets
3. ``cwproc.config``: the configuration as data (TOML <-> frozen dataclasses)
4. ``cwproc.stages``: pure Dataset -> Dataset retrieval steps
5. ``cwproc.products``: metadata (names, units, flags, references) and the writer
6. ``cwproc.pipeline``: the one chain of stages (``run_unit``) and the day streamer
7. clients of the core: ``cwproc.sim``, ``cwproc.batch``, ``cwproc.plots``
8. the user interfaces: ``cwproc.cli``, ``cwproc.api``, ``cwproc.reference_docs``,
   ``cwproc.__main__`` and the package's own ``cwproc/__init__`` (the public API)

A module may import its own layer and any layer below; clients may not import the
user interfaces.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[2] / "cwproc"

LAYERS: tuple[tuple[str, ...], ...] = (
    ("cwproc._version", "cwproc.errors", "cwproc.references", "cwproc.progress", "cwproc.dates"),
    ("cwproc.physics", "cwproc.atables"),
    ("cwproc.io",),
    ("cwproc.config", "cwproc.config_products", "cwproc.configs"),
    ("cwproc.stages",),
    ("cwproc.products",),
    ("cwproc.pipeline",),
    (
        "cwproc.sim",
        "cwproc.batch",
        "cwproc.plots",
        "cwproc.plots_l1",
        "cwproc.plots_compare",
        "cwproc.plot_axes",
    ),
    ("cwproc.cli", "cwproc.api", "cwproc.reference_docs", "cwproc.__main__", "cwproc"),
)

#: third-party packages the physics layer may not use (it is numpy/scipy only)
PHYSICS_FORBIDDEN = ("xarray", "pandas", "netCDF4", "dask", "matplotlib", "click")


def layer_of(module: str) -> int:
    """Index in :data:`LAYERS` of ``module`` (the longest matching prefix)."""
    best, index = "", None
    for i, names in enumerate(LAYERS):
        for name in names:
            inside = module == name or (name != "cwproc" and module.startswith(name + "."))
            if inside and len(name) > len(best):
                best, index = name, i
    if index is None:
        raise KeyError(f"{module} is in no layer: add it to LAYERS")
    return index


def module_name(path: Path) -> str:
    parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def imported_modules(path: Path) -> list[tuple[int, str]]:
    """(line, absolute module) of every import statement in ``path``, at any depth."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    name = module_name(path)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out.extend((node.lineno, alias.name) for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            out.append((node.lineno, target))
            if target == "cwproc" or (node.level and not node.module):
                # ``from cwproc import sim``: the submodules are the imports
                out.extend((node.lineno, f"{target}.{a.name}") for a in node.names)
    return out


def sources() -> list[Path]:
    return sorted(PACKAGE.rglob("*.py"))


def upward_imports() -> list[str]:
    """Every import of a module from a higher layer, as ``file:line: a -> b``."""
    bad = []
    for path in sources():
        here = module_name(path)
        own = layer_of(here)
        for line, target in imported_modules(path):
            root = target.split(".")[0]
            if own == 1 and root in PHYSICS_FORBIDDEN:
                bad.append(f"{path.relative_to(PACKAGE.parent)}:{line}: {here} -> {target}")
            if root != "cwproc" or target == "cwproc":
                continue
            try:
                theirs = layer_of(target)
            except KeyError:
                continue  # an attribute of a module, e.g. ``cwproc.__version__``
            if theirs > own:
                bad.append(f"{path.relative_to(PACKAGE.parent)}:{line}: {here} -> {target}")
    return bad


def test_every_module_has_a_layer():
    for path in sources():
        layer_of(module_name(path))


def test_no_import_runs_up_a_layer():
    bad = upward_imports()
    assert not bad, "imports that run up a layer:\n" + "\n".join(bad)


@pytest.mark.parametrize(
    ("module", "target"),
    [("cwproc.physics.spectra", "cwproc.config"), ("cwproc.io.halo", "cwproc.stages.qc")],
)
def test_the_check_sees_an_upward_import(module, target):
    """The checker itself: an upward import is above its importer."""
    assert layer_of(target) > layer_of(module)
