"""Moved to :mod:`cwproc.physics.root_search` (issue 33): re-exported until stream D."""

from __future__ import annotations

from cwproc.physics.root_search import (  # moved (issue 33): remove in stream D
    Residual,
    bisect,
    bracket_root,
    interpolate,
    replayed_root,
    rising_bracket,
)

__all__ = ["Residual", "bisect", "bracket_root", "interpolate", "replayed_root", "rising_bracket"]
