"""Each layer what its name says (issues 16 and 33): the imports of ``cwproc``, checked.

Every import of ``cwproc`` is read from the source (nothing is imported): ``import`` and
``from ... import`` statements at any depth (inside functions too) and the imports made
from strings (:func:`string_imports`: ``importlib.import_module``, ``__import__``,
``importlib.util.find_spec`` and ``importlib.resources.files`` of a constant, the
``"cwproc.x.y:attr"`` entry points of the lazy command and reader tables, and the
module tables of the packages that import their names on first use). Layers, bottom
up:

0. foundation: ``cwproc._version``, ``errors``, ``references``, ``progress``,
   ``dates``, ``memory`` (the process's allocator, switched on by a client)
1. ``cwproc.physics``: numpy and scipy only; no files, no environment, no terminal
   (:func:`impure_physics`)
2. ``cwproc.tables`` (the table store: disk cache, environment, progress of a build),
   ``cwproc.atables`` (the shipped tables), ``cwproc.metadata`` (the one metadata
   table) and ``cwproc.io`` (files <-> canonical datasets)
3. ``cwproc.config``, ``config_products``, ``configs``: the configuration as data
4. ``cwproc.stages``: pure Dataset -> Dataset steps; they may not import the
   configuration (:data:`FORBIDDEN`): their defaults are literals
5. ``cwproc.products``: the writer, catalogue, Cloudnet files, quality
6. ``cwproc.pipeline``: the one chain of stages (``run_unit``)
7. clients of the core: ``cwproc.sim``, ``batch``, ``plots``
8. the user interfaces: ``cwproc.cli``, ``api``, ``reference_docs``, ``__main__`` and
   the package's own ``cwproc/__init__`` (the public API)

A module may import its own layer and any layer below; no import, eager, lazy or from a
string, may close a cycle (:func:`cycles`). A name of :data:`LAYERS` need not exist yet
(streams of one issue add their packages one after the other); every module that
exists must be in a layer.
"""

from __future__ import annotations

import ast
import functools
import itertools
import re
from collections.abc import Iterator
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[2] / "cwproc"

LAYERS: tuple[tuple[str, ...], ...] = (
    (
        "cwproc._version",
        "cwproc.errors",
        "cwproc.references",
        "cwproc.progress",
        "cwproc.dates",
        "cwproc.memory",
    ),
    ("cwproc.physics",),
    ("cwproc.tables", "cwproc.atables", "cwproc.metadata", "cwproc.io"),
    ("cwproc.config", "cwproc.config_products", "cwproc.configs"),
    ("cwproc.stages",),
    ("cwproc.products",),
    ("cwproc.pipeline",),
    (
        "cwproc.sim",
        "cwproc.batch",
        "cwproc.plots",
    ),
    ("cwproc.cli", "cwproc.api", "cwproc.reference_docs", "cwproc.__main__", "cwproc"),
)

#: packages the physics layer may not use: it is numpy/scipy only, with no files,
#: environment or terminal (the table store, ``cwproc.tables``, has those)
PHYSICS_FORBIDDEN = (
    "xarray",
    "pandas",
    "netCDF4",
    "dask",
    "matplotlib",
    "click",
    "platformdirs",
    "tqdm",
    "tempfile",
)

#: importer -> modules it may not import although they are below it
FORBIDDEN: dict[str, tuple[str, ...]] = {
    # a stage reads no configuration: its defaults are literals (config.py: "Stages
    # never see these objects")
    "cwproc.stages": ("cwproc.config", "cwproc.config_products", "cwproc.configs"),
    # physics reports no progress: the table store draws the bars of a build
    "cwproc.physics": ("cwproc.progress",),
}

#: the calls whose first argument names a module (matched on the end of the callee)
IMPORT_CALLS = (
    ("import_module",),
    ("__import__",),
    ("find_spec",),
    ("resources", "files"),
)
#: the entry-point form "cwproc.x.y:attr" of the lazy tables
ENTRY_POINT = re.compile(r"cwproc(?:\.\w+)*:\w+")


def in_prefix(module: str, name: str) -> bool:
    """Whether ``module`` is ``name`` or inside it (``cwproc`` holds only itself)."""
    return module == name or (name != "cwproc" and module.startswith(name + "."))


def layer_of(module: str) -> int:
    """Index in :data:`LAYERS` of ``module`` (the longest matching prefix)."""
    best, index = "", None
    for i, names in enumerate(LAYERS):
        for name in names:
            if in_prefix(module, name) and len(name) > len(best):
                best, index = name, i
    if index is None:
        raise KeyError(f"{module} is in no layer: add it to LAYERS")
    return index


def module_name(path: Path, package: Path = PACKAGE) -> str:
    parts = list(path.relative_to(package.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def sources(package: Path = PACKAGE) -> list[Path]:
    return sorted(package.rglob("*.py"))


@functools.lru_cache(maxsize=8)
def known_modules(package: Path = PACKAGE) -> frozenset[str]:
    """Every module of the package: sources, packages and compiled extensions (``.c``
    sources of ``setup.py`` or built ``.so`` files: ``from cwproc.io import _hpltok``
    names a module, not an attribute of ``cwproc.io``)."""
    names = {module_name(path, package) for path in sources(package)}
    for pattern in ("*.c", "*.so", "*.pyd"):
        for path in package.rglob(pattern):
            stem = path.name.split(".")[0]
            names.add(module_name(path.parent / f"{stem}.py", package))
    return frozenset(names)


def _callee(func: ast.expr) -> tuple[str, ...]:
    """Dotted parts of a call's function (``importlib.util.find_spec`` -> 3 parts)."""
    parts: list[str] = []
    while isinstance(func, ast.Attribute):
        parts.append(func.attr)
        func = func.value
    if isinstance(func, ast.Name):
        parts.append(func.id)
    return tuple(reversed(parts))


def _module_constants(tree: ast.Module) -> dict[str, str]:
    """Module-level ``NAME = "string"`` assignments."""
    out = {}
    for node in tree.body:
        if isinstance(node, (ast.Assign, ast.AnnAssign)) and isinstance(node.value, ast.Constant):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            if isinstance(node.value.value, str):
                out.update({t.id: node.value.value for t in targets if isinstance(t, ast.Name)})
    return out


def _table_strings(tree: ast.Module) -> Iterator[tuple[int, str]]:
    """Strings of module-level dict values and tuple/list/set items (lazy tables)."""
    for node in tree.body:
        value = node.value if isinstance(node, (ast.Assign, ast.AnnAssign)) else None
        items: list[ast.expr] = []
        if isinstance(value, ast.Dict):
            items = list(value.values)
        elif isinstance(value, (ast.Tuple, ast.List, ast.Set)):
            items = list(value.elts)
        for item in items:
            if isinstance(item, ast.Constant) and isinstance(item.value, str):
                yield item.lineno, item.value


def string_imports(tree: ast.Module, name: str, modules: frozenset[str]) -> list[tuple[int, str]]:
    """(line, module) of the imports ``tree`` (module ``name``) makes from strings.

    Only strings used for imports count, never docstrings or logger names: the
    constant (or module-level constant) argument of the calls of :data:`IMPORT_CALLS`;
    any ``"cwproc.x:attr"`` entry point; in a module calling
    ``import_module(f"{__name__}.{...}")``, the items of its module-level tables that
    name a submodule; in a module calling ``import_module(variable)``, the items of
    its module-level tables that are ``cwproc`` module names.
    """
    constants = _module_constants(tree)
    out: list[tuple[int, str]] = []
    relative = variable = False
    for node in ast.walk(tree):
        if isinstance(node, ast.Constant) and isinstance(node.value, str):
            if ENTRY_POINT.fullmatch(node.value):
                out.append((node.lineno, node.value.partition(":")[0]))
        if not isinstance(node, ast.Call) or not node.args:
            continue
        callee = _callee(node.func)
        if not any(callee[-len(end) :] == end for end in IMPORT_CALLS):
            continue
        arg = node.args[0]
        if isinstance(arg, ast.Constant) and isinstance(arg.value, str):
            out.append((node.lineno, arg.value))
        elif isinstance(arg, ast.Name) and arg.id in constants:
            out.append((node.lineno, constants[arg.id]))
        elif isinstance(arg, ast.JoinedStr) and "__name__" in ast.unparse(arg):
            relative = True
        else:
            variable = True
    for line, text in _table_strings(tree) if relative or variable else ():
        if relative and f"{name}.{text}" in modules:
            out.append((line, f"{name}.{text}"))
        if variable and text.startswith("cwproc."):
            out.append((line, text.partition(":")[0]))
    return out


@functools.lru_cache(maxsize=1024)
def imported_modules(path: Path, package: Path = PACKAGE) -> tuple[tuple[int, str], ...]:
    """(line, absolute name) of every import in ``path``, at any depth and from strings.

    ``from pkg import a`` gives ``pkg.a`` when that is a module (:func:`known_modules`),
    else ``pkg``; a name need not be a module (``cwproc.x.attr``): see :func:`resolve`.
    """
    tree = ast.parse(path.read_text(encoding="utf-8"))
    name = module_name(path, package)
    own_package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    modules = known_modules(package)
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out.extend((node.lineno, alias.name) for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = own_package.split(".")[: len(own_package.split(".")) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            subs = [f"{target}.{a.name}" for a in node.names]
            out.extend((node.lineno, sub) for sub in subs if sub in modules)
            if any(sub not in modules for sub in subs):
                out.append((node.lineno, target))
    return tuple(out + string_imports(tree, name, modules))


def resolve(target: str, modules: frozenset[str]) -> str | None:
    """The ``cwproc`` module ``target`` names (its longest known prefix), else None."""
    parts = target.split(".")
    for n in range(len(parts), 0, -1):
        candidate = ".".join(parts[:n])
        if candidate in modules:
            return candidate
    return None


def upward_imports(package: Path = PACKAGE) -> list[str]:
    """Every import of a higher layer or a forbidden module, as ``file:line: a -> b``."""
    bad = []
    modules = known_modules(package)
    for path in sources(package):
        here = module_name(path, package)
        own = layer_of(here)
        where = path.relative_to(package.parent)
        for line, target in imported_modules(path, package):
            root = target.split(".")[0]
            if own == layer_of("cwproc.physics") and root in PHYSICS_FORBIDDEN:
                bad.append(f"{where}:{line}: {here} -> {target}")
            module = resolve(target, modules) if root == "cwproc" else None
            if module is None or module == "cwproc":
                continue
            forbidden = any(
                in_prefix(here, importer) and any(in_prefix(module, f) for f in targets)
                for importer, targets in FORBIDDEN.items()
            )
            if layer_of(module) > own or forbidden:
                bad.append(f"{where}:{line}: {here} -> {module}")
    return bad


def import_graph(package: Path = PACKAGE) -> dict[str, dict[str, str]]:
    """``{module: {imported module: "file:line"}}`` over every edge (eager, lazy, string)."""
    modules = known_modules(package)
    graph: dict[str, dict[str, str]] = {m: {} for m in modules}
    for path in sources(package):
        here = module_name(path, package)
        for line, target in imported_modules(path, package):
            module = resolve(target, modules) if target.split(".")[0] == "cwproc" else None
            if module is not None and module != here:
                graph[here].setdefault(module, f"{path.relative_to(package.parent)}:{line}")
    return graph


def _components(graph: dict[str, dict[str, str]]) -> list[list[str]]:
    """Strongly connected components of ``graph`` (Tarjan, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is None:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[node])
                if low[node] == index[node]:
                    part = []
                    while True:
                        top = stack.pop()
                        on_stack.discard(top)
                        part.append(top)
                        if top == node:
                            break
                    found.append(sorted(part))
            elif child not in index:
                index[child] = low[child] = len(index)
                stack.append(child)
                on_stack.add(child)
                work.append((child, iter(sorted(graph[child]))))
            elif child in on_stack:
                low[node] = min(low[node], index[child])
    return found


def _cycle_through(graph: dict[str, dict[str, str]], part: list[str]) -> list[str]:
    """One cycle of the component ``part``, from its first module back to it."""
    start, members = part[0], set(part)
    paths = {start: [start]}
    todo = [start]
    while todo:
        node = todo.pop(0)
        for child in sorted(graph[node]):
            if child == start:
                return paths[node] + [start]
            if child in members and child not in paths:
                paths[child] = paths[node] + [child]
                todo.append(child)
    raise AssertionError(f"no cycle through {start}")


def cycles(package: Path = PACKAGE) -> list[str]:
    """Every import cycle, as ``a -> b -> a`` with the ``file:line`` of each edge."""
    graph = import_graph(package)
    out = []
    for part in _components(graph):
        if len(part) > 1:
            path = _cycle_through(graph, part)
            edges = [f"{a} -> {b} ({graph[a][b]})" for a, b in itertools.pairwise(path)]
            out.append(" -> ".join(path) + "\n    " + "\n    ".join(edges))
    return out


#: what the physics layer may not touch: files, the environment, the terminal
_IMPURE_ATTRIBUTES = {
    "os": {"environ", "getenv", "putenv"},
    "sys": {"stderr", "stdout", "stdin"},
    "np": {"save", "savez", "savez_compressed", "savetxt", "load", "loadtxt", "fromfile"},
    "numpy": {"save", "savez", "savez_compressed", "savetxt", "load", "loadtxt", "fromfile"},
}
_IMPURE_METHODS = {"write_text", "write_bytes", "read_text", "read_bytes", "tofile"}
_IMPURE_CALLS = {"print", "open", "input"}


def impure_physics(package: Path = PACKAGE) -> list[str]:
    """Every use of files, environment or terminal in ``cwproc.physics``, ``file:line``."""
    bad: list[tuple[str, int, str]] = []
    for path in sorted((package / "physics").rglob("*.py")):
        where = str(path.relative_to(package.parent))
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            what = None
            if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name):
                if node.attr in _IMPURE_ATTRIBUTES.get(node.value.id, ()):
                    what = f"{node.value.id}.{node.attr}"
            if isinstance(node, ast.Attribute) and node.attr in _IMPURE_METHODS:
                what = f".{node.attr}"
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Name):
                what = f"{node.func.id}(" if node.func.id in _IMPURE_CALLS else what
            if isinstance(node, ast.ImportFrom) and node.module in ("os", "sys"):
                names = {a.name for a in node.names} & _IMPURE_ATTRIBUTES[node.module]
                what = f"from {node.module} import {', '.join(sorted(names))}" if names else what
            if what:
                bad.append((where, node.lineno, what))
    return [f"{where}:{line}: {what}" for where, line, what in sorted(bad)]


def test_every_module_has_a_layer():
    for module in known_modules():
        layer_of(module)


def test_no_import_runs_up_a_layer():
    bad = upward_imports()
    assert not bad, "imports that run up a layer or are forbidden:\n" + "\n".join(bad)


def test_no_import_cycle():
    found = cycles()
    assert not found, "import cycles (eager, lazy or string imports):\n" + "\n".join(found)


def test_physics_uses_no_files_environment_or_terminal():
    bad = impure_physics()
    assert not bad, "physics must be pure (the table store has files):\n" + "\n".join(bad)


@pytest.mark.parametrize(
    ("module", "target"),
    [("cwproc.physics.spectra", "cwproc.config"), ("cwproc.io.halo", "cwproc.stages.qc")],
)
def test_the_check_sees_an_upward_import(module, target):
    """The checker itself: an upward import is above its importer."""
    assert layer_of(target) > layer_of(module)
