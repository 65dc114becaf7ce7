"""Re-export of the one metadata table, now :mod:`cwproc.metadata` (issue 33).

The declarations moved below the stages, so that a stage's output carries units and
long names (:func:`cwproc.metadata.described`). This module keeps the old import path
of the writer, the Cloudnet layout and the tests working until stream D updates them.
"""

from __future__ import annotations

# moved (issue 33): remove in stream D
from cwproc.metadata.products import (  # noqa: F401
    PRODUCT_VARIABLES,
    PRODUCTS,
    VARIABLES,
    apply_metadata,
    attach_declared,
    product_table,
    undeclared_variables,
)
