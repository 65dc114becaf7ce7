"""Re-export of :mod:`cwproc.metadata.l1` (moved in issue 33)."""

from __future__ import annotations

# moved (issue 33): remove in stream D
from cwproc.metadata.l1 import BETA_STANDARD_NAME, L1_VARIABLES  # noqa: F401
