"""Re-export of :mod:`cwproc.metadata.sonic` (moved in issue 33)."""

from __future__ import annotations

# moved (issue 33): remove in stream D
from cwproc.metadata.sonic import (  # noqa: F401
    COMPARISON_VARIABLES,
    SONIC_TURBULENCE_OVERRIDES,
    SONIC_TURBULENCE_REFERENCES,
    SONIC_TURBULENCE_VARIABLES,
)
