"""The disk cache of the table store: arrays computed once per parameter set.

The expensive tables of the turbulence retrieval (the A-functions of
:mod:`cwproc.tables.atable`, the removed share of :mod:`cwproc.tables.removed_share`)
depend only on a few parameters, so each is stored as ``<kind>-<sha256>.npz`` in
:func:`default_cache_dir` (or a given folder), keyed by the SHA-256 of the canonical
JSON of its parameters (:func:`parameter_key`). A file is written atomically
(temporary file in the same folder, then rename), and one that cannot be read, holds
another key or fails the caller's check is computed again, never trusted; an
unwritable folder only costs the computation next time. Stored as ``.npz`` (float64
kept bit for bit), a table read back gives the results of the table computed.

This module is the one place of the library that reads the environment for the cache
(``platformdirs``: ``XDG_CACHE_HOME``, ``HOME``) and writes its files; the physics it
stores is computed without either (:mod:`cwproc.physics`).
"""

from __future__ import annotations

import functools
import hashlib
import os
import re
import tempfile
from collections.abc import Callable
from pathlib import Path

import numpy as np
import platformdirs

from cwproc.physics.canonical_key import parameter_key

__all__ = [
    "PHYSICS_FOLDER",
    "cache_path",
    "cached_arrays",
    "code_digest",
    "default_cache_dir",
    "load_arrays",
    "parameter_key",
    "save_arrays",
]

#: folder of the :mod:`cwproc.physics` sources that :func:`code_digest` hashes
PHYSICS_FOLDER = Path(__file__).resolve().parents[1] / "physics"


def default_cache_dir() -> Path:
    """The user's cache folder of cwproc, ``platformdirs.user_cache_dir("cwproc")``.

    Read from the environment (``XDG_CACHE_HOME``, else ``~/.cache`` on Linux) at each
    call, so that a process that changes it (the tests) is followed.
    """
    return Path(platformdirs.user_cache_dir("cwproc"))


def cache_path(cache_dir: str | os.PathLike | None, kind: str, key: str) -> Path:
    """``<cache_dir>/<kind>-<key>.npz``; default folder :func:`default_cache_dir`."""
    base = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    return base / f"{kind}-{key}.npz"


def save_arrays(path: Path, arrays: dict[str, np.ndarray]) -> None:
    """Write ``arrays`` to ``path`` as ``.npz``, atomically; nothing on an ``OSError``
    (an unwritable cache only costs a rebuild next time)."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}-", suffix=".npz.part", dir=path.parent)
        try:
            with os.fdopen(fd, "wb") as fh:
                np.savez(fh, **arrays)
            os.replace(tmp, path)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise
    except OSError:
        return


def load_arrays(path: Path, key: str) -> dict[str, np.ndarray] | None:
    """The arrays of the cache file at ``path`` written under ``key`` (all but ``key``),
    or ``None`` when it is missing, unreadable or of another key."""
    try:
        with np.load(path, allow_pickle=False) as data:
            if str(data["key"]) != key:
                return None
            return {name: np.array(data[name]) for name in data.files if name != "key"}
    except Exception:  # any unreadable/corrupt file is rebuilt, never trusted
        return None


def cached_arrays(
    kind: str,
    params: dict,
    compute: Callable[[], dict[str, np.ndarray]],
    valid: Callable[[dict[str, np.ndarray]], bool],
    cache_dir: str | os.PathLike | None = None,
) -> dict[str, np.ndarray]:
    """The arrays ``compute()`` returns for ``params``, read from the cache when there.

    Parameters
    ----------
    kind : str
        File name prefix (e.g. ``"removed-share"``).
    params : dict
        Every parameter the arrays depend on, JSON-serialisable, with a version number
        of the numerics (so that a change of the computation is never served old
        results).
    compute : callable
        ``compute() -> {name: ndarray}``, the arrays (``"key"`` is reserved).
    valid : callable
        ``valid(arrays) -> bool``: a file read back is used only when this holds (the
        names, shapes and finite values ``compute`` gives).
    cache_dir : path, optional
        Folder of the cache; default :func:`default_cache_dir`.
    """
    key = parameter_key(params)
    path = cache_path(cache_dir, kind, key)
    arrays = load_arrays(path, key)
    if arrays is not None and valid(arrays):
        return arrays
    arrays = compute()
    save_arrays(path, {"key": np.array(key), **arrays})
    return arrays


#: ``from cwproc.physics.X import``, ``import cwproc.physics.X``
_SUBMODULE = re.compile(r"^\s*(?:from|import)\s+cwproc\.physics\.(\w+)", re.MULTILINE)
#: ``from cwproc.physics import a, b`` (one line or parenthesised)
_NAMES = re.compile(r"^\s*from\s+cwproc\.physics\s+import\s+(\([^)]*\)|[^\n]*)", re.MULTILINE)


def _physics_imports(text: str) -> set[str]:
    """The ``cwproc.physics`` modules the source ``text`` imports (any depth, any form)."""
    found = {f"cwproc.physics.{m}" for m in _SUBMODULE.findall(text)}
    for group in _NAMES.findall(text):
        for item in group.strip("()").replace("\n", ",").split(","):
            name = item.split("#")[0].split(" as ")[0].strip()
            if name:
                found.add(f"cwproc.physics.{name}")
    return found


@functools.lru_cache(maxsize=8)
def code_digest(module: str, folder: str | None = None) -> str:
    """SHA-256 (hex) of the code of ``module`` and every ``cwproc.physics`` module it uses.

    The modules are followed through their imports (closure within ``cwproc.physics``)
    and their source texts hashed, so that any change of the code that computes cached
    arrays gives them a new key (a change of a docstring too: a rebuild, never a stale
    result). The modules are named by their dotted names, not their paths, so the digest
    is the same wherever the package is installed. Computed once per process and module
    (a few tens of ms). ``folder``: where the modules are (default
    :data:`PHYSICS_FOLDER`).
    """
    root = Path(folder) if folder is not None else PHYSICS_FOLDER
    seen: dict[str, str] = {}
    todo = [module]
    while todo:
        name = todo.pop()
        if name in seen:
            continue
        path = root / (name.removeprefix("cwproc.physics.") + ".py")
        if not path.is_file():  # a package attribute, not a module of its own
            seen[name] = ""
            continue
        text = path.read_text(encoding="utf-8")
        todo.extend(_physics_imports(text))
        seen[name] = text
    text = "\n".join(f"{name}\n{seen[name]}" for name in sorted(seen))
    return hashlib.sha256(text.encode()).hexdigest()
