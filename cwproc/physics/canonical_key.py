"""The key of a parameter set: SHA-256 of its canonical JSON.

Tables computed from a few parameters (the A-functions of :mod:`cwproc.physics.atable`,
the removed-share curves of :mod:`cwproc.physics.removed_share`) are named by this key,
in memory and in the table store (:mod:`cwproc.tables.store`). Pure: no files.
"""

from __future__ import annotations

import hashlib
import json


def parameter_key(params: dict) -> str:
    """SHA-256 (hex) of the canonical JSON of ``params`` (keys sorted, no spaces)."""
    text = json.dumps(params, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()
