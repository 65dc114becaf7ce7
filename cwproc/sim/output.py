"""Where the virtual instrument writes: a fresh folder of simulated files, the truth JSON."""

from __future__ import annotations

import json
import os
from pathlib import Path

from cwproc.io.netcdf import write_bytes_atomic


def fresh_folder(folder: str | os.PathLike, pattern: str) -> Path:
    """Create ``folder`` and remove the files matching ``pattern`` a former run left in it.

    A simulated series replaces the previous one whole, so that ``retrieve`` on the folder
    never mixes two simulations.
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    for old in folder.glob(pattern):
        old.unlink()
    return folder


def write_truth(path: str | os.PathLike, truth: object, *, sort_keys: bool = True) -> Path:
    """Write the truth of a simulation as indented JSON, whole or not at all; returns ``path``."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    text = json.dumps(truth, indent=2, sort_keys=sort_keys) + "\n"
    return write_bytes_atomic(path, text.encode("utf-8"))
