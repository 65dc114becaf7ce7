"""``sitecustomize`` of the new user's environment (tests/test_readme.py): only what
cwproc declares.

The environment sees the site-packages of the interpreter that runs the tests (a ``.pth``
file adds them), so that the test does not unpack half a gigabyte of wheels; this
module, copied into it as ``sitecustomize.py``, makes it behave as the fresh environment
of ``pip install .`` would. Those site-packages (and what their ``.pth`` files added)
leave ``sys.path``; a finder at the
end of ``sys.meta_path`` finds a top-level module there only when it belongs to a
distribution that cwproc's installed metadata requires, directly or through its
requirements (extras left out, environment markers evaluated), and
``importlib.metadata`` sees only those distributions. Any other module is absent, as in
an environment where it was never installed: ``importlib.util.find_spec`` gives
``None``, an optional import (``try: import dask``) takes the path it takes there, and a
module cwproc needs but does not declare fails the command that imports it.

Modules of the environment itself (cwproc, pip) and of the standard library are not
affected. A requirement installed at a version it does not accept is printed to stderr.
Every module refused is appended to the file named by ``CWPROC_TEST_REFUSED_IMPORTS``
(one name a line) for the test to report.
"""

from __future__ import annotations

import importlib.abc
import importlib.machinery
import importlib.metadata
import os
import sys
import sysconfig

_ENVIRONMENT = os.path.realpath(sys.prefix) + os.sep
_STDLIB = tuple(
    os.path.realpath(sysconfig.get_path(name, vars={"base": sys.base_prefix})) + os.sep
    for name in ("stdlib", "platstdlib")
)


def _hidden(entry: str) -> bool:
    """Whether a ``sys.path`` entry is outside the environment and the standard library
    (a site-packages folder of another interpreter or environment, or what its ``.pth``
    files added)."""
    if not entry:
        return False  # the current folder
    real = os.path.realpath(entry) + os.sep
    if real.startswith(_ENVIRONMENT):
        return False
    site_folder = "site-packages" in real or "dist-packages" in real
    return site_folder or not real.startswith(_STDLIB)


def _top_level(dist: importlib.metadata.Distribution) -> set[str]:
    """Top-level module names of an installed distribution (from its file list, else
    from its ``top_level.txt``)."""
    if dist.files is None:
        return set((dist.read_text("top_level.txt") or "").split())
    names = set()
    for path in dist.files:
        parts = path.parts
        if not parts or parts[0].endswith((".dist-info", ".egg-info")) or parts[0] == "..":
            continue
        first = parts[0]
        if len(parts) == 1:
            if not first.endswith((".py", ".so", ".pyd")):
                continue
            first = first.split(".")[0]
        names.add(first)
    return names


class DeclaredOnly(importlib.abc.MetaPathFinder):
    """Finds, on the hidden base paths, the modules and distributions cwproc declares."""

    def __init__(self, hidden: list[str]) -> None:
        self.hidden = hidden
        self._allowed: tuple[set[str], set[str]] | None = None
        self._reading = False

    def _closure(self) -> tuple[set[str], set[str]]:
        """(module names, normalised distribution names) of cwproc's requirements."""
        if self._allowed is None:
            self._reading = True  # packaging comes from the hidden paths
            try:
                self._allowed = self._read_closure()
            finally:
                self._reading = False
        return self._allowed

    def _read_closure(self) -> tuple[set[str], set[str]]:
        from packaging.requirements import Requirement
        from packaging.utils import canonicalize_name

        own = [p for p in sys.path if not _hidden(p)]
        found = list(importlib.metadata.distributions(name="cwproc", path=own))
        if not found:
            return set(), set()  # pip's own process, before cwproc is installed
        modules, seen, todo = set(), set(), [(found[0], None)]
        while todo:
            dist, req = todo.pop()
            if req is not None and not req.specifier.contains(dist.version, prereleases=True):
                print(f"sitecustomize: {req} installed at {dist.version}", file=sys.stderr)
            key = canonicalize_name(dist.metadata["Name"])
            if key in seen:
                continue
            seen.add(key)
            modules |= _top_level(dist)
            for text in dist.requires or []:
                sub = Requirement(text)
                if sub.marker is not None and not sub.marker.evaluate({"extra": ""}):
                    continue
                match = list(importlib.metadata.distributions(name=sub.name, path=sys.path))
                match += list(importlib.metadata.distributions(name=sub.name, path=self.hidden))
                if match:
                    todo.append((match[0], sub))
                else:
                    print(f"sitecustomize: {sub} is not installed", file=sys.stderr)
        return modules, seen

    def find_spec(self, name, path=None, target=None):
        if path is not None or "." in name:
            return None  # submodules go through their package
        free = self._reading or name in sys.stdlib_module_names
        if not free and name not in self._closure()[0]:
            spec = importlib.machinery.PathFinder.find_spec(name, self.hidden)
            if spec is not None:
                log = os.environ.get("CWPROC_TEST_REFUSED_IMPORTS")
                if log:
                    with open(log, "a", encoding="utf-8") as fh:
                        fh.write(name + "\n")
            return None
        return importlib.machinery.PathFinder.find_spec(name, self.hidden)

    def find_distributions(self, context=None):
        if context is None:
            context = importlib.metadata.DistributionFinder.Context()
        if self._reading or (context.path is not sys.path and context.path != sys.path):
            return iter(())  # a search of given folders, not of the environment
        from packaging.utils import canonicalize_name

        allowed = self._closure()[1]
        found = importlib.metadata.MetadataPathFinder.find_distributions(
            importlib.metadata.DistributionFinder.Context(name=context.name, path=self.hidden)
        )
        return (d for d in found if canonicalize_name(d.metadata["Name"]) in allowed)


def _finder_file(finder) -> str | None:
    """The file of the module that defines a ``sys.meta_path`` finder."""
    cls = finder if isinstance(finder, type) else type(finder)
    return getattr(sys.modules.get(cls.__module__), "__file__", None)


def _install() -> None:
    """The hidden paths out of ``sys.path``, the finders their ``.pth`` files installed
    (e.g. of an editable cwproc elsewhere) out of ``sys.meta_path``, this finder last."""
    hidden = [p for p in sys.path if _hidden(p)]
    sys.path[:] = [p for p in sys.path if not _hidden(p)]
    sys.meta_path[:] = [
        f
        for f in sys.meta_path
        if not (_finder_file(f) and _hidden(os.path.dirname(_finder_file(f))))
    ]
    sys.meta_path.append(DeclaredOnly(hidden))


_install()
