"""What a Stream Line ``.hpl`` file says of itself, checked: attributes, rays, options.

Shared by the reader of one file (:mod:`cwproc.io.halo`) and the reader of a day of
files (:mod:`cwproc.io.halo_files`): the global attributes of the scan dataset taken
from the header (:func:`scan_attrs`), the plausibility of each ray line's decimal time
and pointing (:func:`bad_ray`, :func:`check_rays`), and the reader's (absent) options.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from cwproc.errors import ConfigError, InputFileError
from cwproc.io.halo_header import HplHeader

INSTRUMENT = "Halo Photonics Stream Line"
INSTRUMENT_KIND = "streamline"


def check_no_options(options: dict) -> None:
    """Refuse ``[reader.hpl]`` options: the ``.hpl`` reader takes none.

    Raises
    ------
    ConfigError
        ``options`` is not empty; the message names the table and the options.
    """
    if options:
        raise ConfigError(
            "[reader.hpl]", ", ".join(sorted(options)), "the .hpl reader takes no options"
        )


def bad_ray(rays: np.ndarray) -> tuple[int, str] | None:
    """First ray whose decimal time or pointing no instrument writes, and the problem.

    Parameters
    ----------
    rays : numpy.ndarray
        One row per ray line: decimal time (h), azimuth (deg), elevation (deg), ...

    Returns
    -------
    (int, str) or None
        Index of the first bad ray and what is wrong with it; None when all are
        plausible (time 0-48 h, azimuth -360-720 deg, elevation -90-270 deg).
    """
    checks = (
        ((rays[:, 0] < 0) | (rays[:, 0] >= 48), "decimal time {} h is outside 0-48 h", 0),
        ((rays[:, 1] < -360) | (rays[:, 1] > 720), "azimuth {} deg is out of range", 1),
        ((rays[:, 2] < -90) | (rays[:, 2] > 270), "elevation {} deg is out of range", 2),
    )
    for bad, message, column in checks:
        idx = np.flatnonzero(bad)
        if idx.size:
            i = int(idx[0])
            return i, message.format(rays[i, column])
    return None


def check_rays(path: str | os.PathLike, rays: np.ndarray, ray_lines: np.ndarray) -> None:
    """Decimal time and pointing angles within what an instrument can write.

    Raises
    ------
    InputFileError
        The first implausible ray (:func:`bad_ray`), naming its line
        (``ray_lines``: the 1-based line number of each ray).
    """
    bad = bad_ray(rays)
    if bad is not None:
        raise InputFileError(path, bad[1], int(ray_lines[bad[0]]))


def scan_attrs(path: Path, header: HplHeader) -> dict[str, object]:
    """The global attributes of the scan dataset of one ``.hpl`` file, from its header."""
    attrs: dict[str, object] = {
        "instrument": INSTRUMENT,
        "instrument_kind": INSTRUMENT_KIND,
        "system_id": header.system_id,
        "source_files": [path.name],
        "scan_type": header.scan_type,
        "gate_length_m": header.gate_length_m,
        "homodyne": 0,
        "points_per_gate": header.points_per_gate,
        "pulses_per_ray": header.pulses_per_ray,
        "focus_range_m": header.focus_range_m,
        "velocity_resolution_m_s": header.velocity_resolution_m_s,
        "header_filename": header.filename,
        "header_start_time": np.datetime_as_string(header.start_time, unit="ms") + "Z",
        "header_rays_in_file": header.rays_in_file,
        "range_formula": header.range_formula,
    }
    if header.instrument_spectral_width_m_s is not None:
        attrs["instrument_spectral_width_m_s"] = header.instrument_spectral_width_m_s
    return attrs
