"""What a file is, apart from its reader: formats, their kinds, header identities.

The names every reader and the dispatch of :mod:`cwproc.io` share: :class:`Format`,
:data:`KIND`, :class:`FileIdentity` and :data:`NETCDF_LOCK`. They live here, not in
``cwproc/io/__init__.py``, so that a reader imports them without importing the
dispatch that imports the readers (no import cycle); :mod:`cwproc.io` re-exports them.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field
from enum import StrEnum

import numpy as np

#: held by every open, read and write of a NetCDF file by cwproc: libnetcdf and HDF5 are
#: not thread-safe, and ``retrieve`` reads the inputs it cannot identify from a header
#: in two threads (two NetCDF scans opened at once crashed the process)
NETCDF_LOCK = threading.RLock()


class Format(StrEnum):
    """File formats cwproc reads."""

    HPL = "hpl"  # Halo Photonics Stream Line
    SCAN_NETCDF = "scan_netcdf"  # cwproc canonical scan dataset (e.g. cw line of sight)
    ZEPHIR_CSV = "zephir_csv"  # ZephIR 300 Waltz / CSV Converter export
    WINDCUBE_STA = "windcube_sta"  # Leosphere WindCube .sta/.stdsta statistics
    WINDCUBE_RTD = "windcube_rtd"  # Leosphere WindCube .rtd real-time lines of sight
    TOA5 = "toa5"  # Campbell Scientific ASCII
    TOB1 = "tob1"  # Campbell Scientific binary
    GHG = "ghg"  # LI-COR GHG .data text
    METEO2 = "meteo2"  # IAO SB RAS Meteo-2 text log (configurable layout)
    GILL = "gill"  # Gill WindMaster / R3 UVW ASCII
    HALO_BACKGROUND = "halo_background"  # Stream Line Background_DDMMYY-HHMMSS.txt


@dataclass(frozen=True)
class FileIdentity:
    """What a file's header says it is, without its data: attributes and ray times.

    ``time`` holds the times known from the header (for ``.hpl``: the first ray's).
    ``header`` and ``offset`` keep what the reader parsed (a Stream Line's
    :class:`~cwproc.io.halo_header.HplHeader` and the byte offset of its data lines),
    so that the read of its data need not parse the header again; None when unknown.
    """

    attrs: dict
    time: np.ndarray
    header: object = field(default=None, compare=False, repr=False)
    offset: int | None = field(default=None, compare=False, repr=False)


#: what each format holds: "scan", "wind_record", "sonic" or "background" (a Stream Line
#: background profile: used to correct the SNR of the scans beside it, never a product)
KIND: dict[Format, str] = {
    Format.HPL: "scan",
    Format.SCAN_NETCDF: "scan",
    Format.ZEPHIR_CSV: "wind_record",
    Format.WINDCUBE_STA: "wind_record",
    Format.WINDCUBE_RTD: "wind_record",
    Format.TOA5: "sonic",
    Format.TOB1: "sonic",
    Format.GHG: "sonic",
    Format.METEO2: "sonic",
    Format.GILL: "sonic",
    Format.HALO_BACKGROUND: "background",
}
