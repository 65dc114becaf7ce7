"""Attach the CF attributes of a canonical input dataset when a reader builds it.

The declarations themselves (:class:`~cwproc.metadata.canonical.VarMeta`, the scan,
wind-record and sonic tables) live in :mod:`cwproc.metadata.canonical`, the one
metadata table; every reader calls :func:`with_canonical_attrs` on the dataset it
returns.
"""

from __future__ import annotations

import xarray as xr

from cwproc.metadata.canonical import DATASET_VARIABLES, DatasetKind, attach_attrs


def with_canonical_attrs(ds: xr.Dataset, kind: DatasetKind = "scan") -> xr.Dataset:
    """The canonical dataset ``ds`` of ``kind`` with the CF attributes of its variables.

    Called by every reader on the dataset it returns.

    Parameters
    ----------
    ds : xarray.Dataset
        A scan, wind-record or sonic dataset.
    kind : {"scan", "wind_record", "sonic"}
        Which canonical dataset it is.
    """
    return attach_attrs(ds, DATASET_VARIABLES[kind])
