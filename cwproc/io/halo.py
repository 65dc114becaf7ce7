"""Halo Photonics Stream Line ``.hpl`` files: reader and writer.

The layout is described in ``real_data/FORMATS.md`` section 1: a header of 17 lines,
then one block per ray, made of one *ray line* (decimal hours, azimuth, elevation and,
on most instruments, pitch and roll) and ``Number of gates`` *gate lines* (gate index,
Doppler velocity, intensity = SNR + 1, attenuated backscatter and, when spectral width
is switched on, the spectral width).

:func:`read_hpl` parses the header (:mod:`cwproc.io.halo_header`), tokenises the
whole body with one call of the compiled or the pandas C tokenizer, checks the block
structure with array operations, and only when a check fails walks the offending ray
block line by line to name the first bad line (:mod:`cwproc.io.halo_body`).
:func:`cwproc.io.halo_files.read_hpl_files` reads many files (a day of scans) into one
dataset: their data lines are counted first, then each file is parsed straight into the
arrays of the whole record. :func:`write_hpl` writes a
canonical scan dataset back in the instrument's layout (used by the simulator and the
benchmarks).

Notes
-----
* **Time.** The ray line gives decimal hours since 00:00 UTC of the date in
  ``Start time`` (the file states no zone; UTC in practice). A file that crosses
  midnight has hours >= 24 or wraps back to 0; a wrap (a step back of more than
  12 h) adds 24 h to the rays after it, and a first ray more than 12 h before the
  start time belongs to the next day. Times are rounded to the microsecond.
* **Angles.** Azimuth is clockwise from north, returned in [0, 360) (``360.00`` -> 0).
  An elevation above 90 deg (beam over the zenith, e.g. ``180.01``) is the direction
  azimuth + 180 deg at elevation 180 deg - el. ``-0.00`` becomes 0
  (:func:`cwproc.physics.geometry.normalise_pointing`).
* **Sign.** Doppler velocity is positive away from the lidar (the Halo convention).
* **Missing data.** There is no fill value: every gate has numbers; noise gates have
  intensity close to 1 (SNR close to 0) and must be screened by SNR downstream.
* **Header quirks.** ``No. of rays in file`` (or ``No. of waypoints in file``) is
  unreliable and only kept as an attribute; the column count of the first gate line
  (4 or 5), not the header, says whether spectral width is present; header numbers may
  use a decimal comma (``30,0``, ``14:00:01,23``).
"""

from __future__ import annotations

import functools
import os
from pathlib import Path
from typing import Protocol

import numpy as np
import pandas as pd
import xarray as xr

from cwproc.errors import CwprocError, InputFileError
from cwproc.io.halo_body import (
    content_end,
    diagnose,
    fields_of_row,
    single_space_ok,
    structure_problem,
    tokenize_body,
)
from cwproc.io.halo_header import (
    FOCUS_INFINITY,
    HEADER_LINES,
    LINE_END,
    parse_hpl_header,
    split_header,
)
from cwproc.io.hpl_attrs import check_no_options, check_rays, scan_attrs
from cwproc.io.identity import FileIdentity
from cwproc.io.netcdf import write_bytes_atomic
from cwproc.metadata.canonical import DECLARED_ATTRS, SCAN_VARIABLES
from cwproc.physics.geometry import normalise_pointing
from cwproc.physics.scan_numbering import scan_indices

try:  # the optional compiled tokenizer (setup.py)
    from cwproc.io import _hpltok
except ImportError:
    _hpltok = None


class Fed(Protocol):
    """What :func:`read_header_body_offset` feeds the bytes of a file to: a
    :mod:`hashlib` object, or anything with its ``update``."""

    def update(self, data: bytes | memoryview, /) -> None: ...


#: hours of a step back in decimal time that marks a wrap at midnight
_WRAP_HOURS = 12.0


#: bytes read first for the header (a Stream Line header is about 1 kB)
_HEAD_BYTES = 1 << 16


def read_header_and_body(path: Path) -> tuple[list[str], bytes]:
    """The 17 header lines and the data lines of a file, each read once from disk.

    The body is read straight after the header (no copy of the whole file); it keeps
    a final line end (and spaces before it), which the tokenizer ignores, but not
    further blank lines.

    Raises
    ------
    InputFileError
        The file cannot be read, or its header is cut short (see :func:`split_header`).
    """
    lines, body, _ = read_header_body_offset(path)
    return lines, body


#: longest data line a Stream Line writes is under 100 bytes (five numbers); a stretch of
#: the body this long without a line end is not data lines
MAX_LINE_BYTES = 4096
#: bytes looked at in each sampled window of the body (see :func:`check_body_sampled`)
SAMPLE_BYTES = 1 << 16
#: windows sampled through the body before it is read
SAMPLES = 32


def body_problem(window: bytes) -> tuple[str, int] | None:
    """What makes ``window`` (a stretch of a body) not data lines and where, or None.

    A NUL byte (a sparse or zero-filled file, binary junk) or :data:`MAX_LINE_BYTES`
    without a line end.
    """
    nul = window.find(b"\x00")
    if nul >= 0:
        return "a NUL byte", nul
    for start in range(0, len(window) - MAX_LINE_BYTES + 1, MAX_LINE_BYTES):
        end = start + MAX_LINE_BYTES
        if window.find(b"\n", start, end) < 0 and window.find(b"\r", start, end) < 0:
            return f"{MAX_LINE_BYTES} bytes without a line end", start
    return None


def check_body_sampled(path: str | os.PathLike, f, offset: int) -> None:
    """Refuse a body that is not data lines before reading it (issue 34.4).

    :data:`SAMPLES` windows of :data:`SAMPLE_BYTES` spread evenly through the body
    (the file's size from ``fstat``) are looked at with :func:`body_problem`: a sparse
    2 GB file behind a valid header was read whole (4.3 GB of memory, 73 s) before its
    NUL bytes were found. Costs a few reads however big the file; ``f`` is left at
    ``offset``. A damaged stretch between the windows is still found by the full checks
    after the read.
    """
    size = os.fstat(f.fileno()).st_size - offset
    if size <= SAMPLE_BYTES * SAMPLES:
        return  # small: read whole, checked whole
    step = size // SAMPLES
    for k in range(SAMPLES):
        at = offset + k * step
        window = os.pread(f.fileno(), SAMPLE_BYTES, at)
        problem = body_problem(window)
        if problem is not None:
            what, where = problem
            raise InputFileError(
                path,
                f"{what} at byte {at + where} of a {size + offset}-byte file: not Stream "
                "Line data lines (a sparse, overwritten or binary file); refused unread",
            )


def read_header_body_offset(
    path: Path, digest: Fed | None = None, offset: int | None = None
) -> tuple[list[str], bytes, int]:
    """As :func:`read_header_and_body`, and the byte offset of the body in the file.

    The offset lets :func:`cwproc.io.halo_files.read_hpl_files` read the data lines a
    second time without splitting the header again. With ``digest`` (a
    :mod:`hashlib` object, or anything with its ``update``), every byte of the file is
    fed to it as read: the file's checksum taken by the same read. With ``offset``
    (the offset an earlier read of the header found), the header is not split again:
    its lines are not returned (an empty list) and the data lines are read from there.
    """
    try:
        with path.open("rb") as f:
            if offset is not None:
                lines, head = [], f.read(offset)
            else:
                head = f.read(_HEAD_BYTES)
                try:
                    lines, offset = split_header(path, head)
                except InputFileError:
                    if len(head) < _HEAD_BYTES:
                        raise
                    head += f.read()  # huge header lines
                    lines, offset = split_header(path, head)
                f.seek(offset)
            check_body_sampled(path, f, offset)
            body = f.read()
    except OSError as exc:
        raise InputFileError(path, f"cannot read: {exc.strerror or exc}") from None
    if digest is not None:
        digest.update(memoryview(head)[:offset])
        digest.update(body)
    end = content_end(body)
    tail = body[end:]
    if tail.lstrip(b" ") not in (b"", b"\n", b"\r\n", b"\r"):
        body = body[:end]  # blank lines after the data: drop them (copies the body)
    return lines, body, offset


def decimal_hours_to_time(hours: np.ndarray, start_time: np.datetime64) -> np.ndarray:
    """UTC times from Halo decimal hours since 00:00 of the start date.

    Parameters
    ----------
    hours : ndarray
        Decimal time of each ray (h).
    start_time : datetime64
        ``Start time`` of the header.

    Returns
    -------
    ndarray of datetime64[ns]
        Monotonic across midnight: a step back of more than 12 h adds 24 h to the
        following rays, and a first ray more than 12 h before the start time of day
        is on the next day. Rounded to the microsecond.
    """
    day = start_time.astype("datetime64[D]")
    start_hours = (start_time - day) / np.timedelta64(1, "h")
    hours = np.asarray(hours, dtype=np.float64)
    wraps = np.concatenate([[0], np.cumsum(np.diff(hours) < -_WRAP_HOURS)])
    offset = 24.0 * wraps
    if hours.size and hours[0] < start_hours - _WRAP_HOURS:
        offset = offset + 24.0
    micro = np.rint((hours + offset) * 3.6e9).astype(np.int64)
    return (day.astype("datetime64[us]") + micro.astype("timedelta64[us]")).astype("datetime64[ns]")


def read_hpl(path: str | os.PathLike, **options: object) -> xr.Dataset:
    """Read a Halo Photonics Stream Line ``.hpl`` file into a canonical scan dataset.

    Parameters
    ----------
    path : path-like
        The ``.hpl`` file (any variant of ``real_data/FORMATS.md`` section 1: Stare,
        VAD, user scans; 3- or 5-field ray lines; 4- or 5-column gate lines; CRLF, LF
        or CR; with or without a final newline).
    **options
        ``[reader.hpl]`` configuration table; the reader takes no options (any key
        raises :class:`cwproc.errors.ConfigError`).

    Returns
    -------
    xarray.Dataset
        Dims ``ray``, ``range``; coords ``time`` (UTC), ``azimuth`` (deg, [0, 360)),
        ``elevation`` (deg), ``range`` (m, gate centre), ``scan``; data
        ``radial_velocity`` (m s-1, positive away from the lidar), ``snr`` (intensity
        - 1), ``beta`` (m-1 sr-1), ``spectral_width`` (m s-1, when present), ``pitch``
        and ``roll`` (deg, when present); header values in ``attrs``.

    Raises
    ------
    InputFileError
        Empty file, another format, garbled header, non-numeric field, a gate count
        that does not match the body, a gate index that restarts without a ray line,
        a truncated last ray: the message names the file and the 1-based line.
    """
    check_no_options(options)
    path = Path(path)
    lines, body = read_header_and_body(path)
    header = parse_hpl_header(path, lines)
    if content_end(body) == 0:
        raise InputFileError(path, "no data after the header", HEADER_LINES + 1)
    nul = body.find(b"\x00")
    if nul >= 0:
        line = HEADER_LINES + 1 + len(LINE_END.findall(body, 0, nul))
        raise InputFileError(path, "NUL byte in the data", line)

    n_gates = header.n_gates
    # the pandas tokenizer's layout (decided lazily when the compiled one is there)
    single_space = None if _hpltok is not None else single_space_ok(body)
    columns = tokenize_body(path, body, single_space=single_space)
    problem = structure_problem(columns, n_gates)
    if problem is not None and single_space:  # judge damage with the reference tokenizer
        columns = tokenize_body(path, body, single_space=False)
        problem = structure_problem(columns, n_gates)
    if problem is not None:
        raise diagnose(path, body, *problem)
    n_rows = columns[0].size
    block = n_gates + 1
    ray_fields = fields_of_row(columns, 0)
    gate_fields = fields_of_row(columns, 1)
    n_rays = n_rows // block
    grids = [col.reshape(n_rays, block) for col in columns]
    rays = np.column_stack([g[:, 0] for g in grids])
    ray_lines = HEADER_LINES + 1 + np.arange(n_rays) * block
    check_rays(path, rays, ray_lines)

    time = decimal_hours_to_time(rays[:, 0], header.start_time)
    azimuth, elevation = normalise_pointing(rays[:, 1], rays[:, 2])
    gates = {"radial_velocity": grids[1], "snr": grids[2], "beta": grids[3]}
    if gate_fields == 5:
        gates["spectral_width"] = grids[4]
    per_ray = {"pitch": rays[:, 3], "roll": rays[:, 4]} if ray_fields == 5 else {}
    scan, numbering_attrs = scan_indices(time, azimuth, elevation, scan_type=header.scan_type)
    ds = scan_dataset(
        gates,
        per_ray,
        time=time,
        azimuth=azimuth,
        elevation=elevation,
        ranges=header.gate_ranges(),
        scan=(scan, numbering_attrs),
        attrs=scan_attrs(path, header),
    )
    return ds


def read_hpl_identity(path: str | os.PathLike) -> FileIdentity:
    """What a ``.hpl`` file is, from its header and first ray line only (no data).

    For grouping files into product units without reading them (instrument, system
    id, UTC day): the attributes :func:`read_hpl` gives and a ``time(ray)`` of the first
    ray alone (the earliest: ray times run forward, across midnight too, see
    :func:`decimal_hours_to_time`). The data are checked when the file is read.

    Raises
    ------
    InputFileError
        The file cannot be read, its header is garbled, or no ray line follows it.
    """
    path = Path(path)
    try:
        with path.open("rb") as f:
            head = f.read(_HEAD_BYTES)
    except OSError as exc:
        raise InputFileError(path, f"cannot read: {exc.strerror or exc}") from None
    lines, offset = split_header(path, head)
    header = parse_hpl_header(path, lines)
    first = head[offset:].lstrip(b"\r\n").split(b"\n", 1)[0].split(b"\r", 1)[0].split()
    try:
        hours = float(first[0])
    except (IndexError, ValueError):
        raise InputFileError(path, "no ray line after the header", HEADER_LINES + 1) from None
    time = decimal_hours_to_time(np.array([hours]), header.start_time)
    return FileIdentity(attrs=scan_attrs(path, header), time=time, header=header, offset=offset)


def scan_dataset(
    gates: dict[str, np.ndarray],
    per_ray: dict[str, np.ndarray],
    *,
    time: np.ndarray,
    azimuth: np.ndarray,
    elevation: np.ndarray,
    ranges: np.ndarray,
    scan: tuple[np.ndarray, dict[str, object]],
    attrs: dict[str, object],
) -> xr.Dataset:
    """The canonical scan dataset from parsed arrays, built from ``xarray.Variable``s.

    Parameters
    ----------
    gates : dict of ndarray
        ``radial_velocity`` (m s-1), ``snr`` given as the file's intensity (SNR + 1,
        converted here), ``beta`` (m-1 sr-1), optional ``spectral_width`` (m s-1): each
        of shape (ray, 1 + gate), column 0 (the ray line's field) is dropped.
    per_ray : dict of ndarray
        ``pitch`` and ``roll`` (deg) when the ray lines have them.
    time, azimuth, elevation : ndarray
        Per-ray coordinates (datetime64[ns]; deg).
    ranges : ndarray
        Gate centres (m).
    scan : (ndarray, dict)
        Scan index of each ray and its attributes.
    attrs : dict
        Dataset attributes.
    """
    ray_range = ("ray", "range")
    variables: dict[str, xr.Variable] = {}
    for name, grid in gates.items():
        values = grid[:, 1:] - 1.0 if name == "snr" else np.ascontiguousarray(grid[:, 1:])
        variables[name] = _canonical(name, ray_range, values)
    for name, values in per_ray.items():
        variables[name] = _canonical(name, ("ray",), np.array(values, dtype=np.float64))
    coords = {
        "time": _canonical("time", ("ray",), time, coord=True),
        "azimuth": _canonical("azimuth", ("ray",), azimuth, coord=True),
        "elevation": _canonical("elevation", ("ray",), elevation, coord=True),
        "range": _canonical("range", ("range",), ranges, coord=True),
        "scan": _canonical("scan", ("ray",), scan[0], scan[1], coord=True),
    }
    return _assembled(variables, coords, attrs)


@functools.lru_cache(maxsize=64)
def _declared_attrs(name: str, dtype: np.dtype, coord: bool) -> dict[str, object]:
    """The attributes :func:`cwproc.metadata.canonical.attach_attrs` declares for a scan variable
    of this name and dtype (computed once per process; copied for each variable)."""
    meta = SCAN_VARIABLES.get(name)
    if meta is None:
        return {}
    attrs = meta.attrs()
    for key in ("flag_values", "flag_masks"):
        if key in attrs and dtype.kind in "iu":
            attrs[key] = np.asarray(attrs[key], dtype=dtype)
    if dtype.kind == "M":
        attrs.pop("units", None)
    if coord:
        attrs["coverage_content_type"] = "coordinate"
    return attrs


def _canonical(
    name: str,
    dims: tuple[str, ...],
    values: np.ndarray,
    attrs: dict[str, object] | None = None,
    *,
    coord: bool = False,
) -> xr.Variable:
    """A variable of the canonical scan dataset with its declared attributes: what
    ``with_canonical_attrs(ds, "scan")`` makes of it, without copying the dataset (a
    quarter of the time of reading a 10 kB file went to that copy and its loop)."""
    kept = {k: v for k, v in (attrs or {}).items() if k not in DECLARED_ATTRS}
    declared = _declared_attrs(name, values.dtype, coord)
    for key, value in declared.items():
        kept[key] = value.copy() if isinstance(value, np.ndarray) else value
    if values.dtype.kind not in "fiuM" or (values.dtype.kind == "M" and values.dtype != "M8[ns]"):
        return xr.Variable(dims, values, kept)  # what xarray converts, converted by it
    return xr.Variable(dims, values, kept, fastpath=True)  # a checked ndarray: no conversion


def _assembled(
    variables: dict[str, xr.Variable], coords: dict[str, xr.Variable], attrs: dict[str, object]
) -> xr.Dataset:
    """``xr.Dataset(variables, coords=coords, attrs=attrs)`` of a scan dataset (dims
    ``ray`` and ``range``, ``range`` its only indexed coordinate).

    Assembled directly from the checked variables (``Dataset._construct_direct`` and
    the ``range`` index): the public constructor's alignment and merge took 300 us of a
    10 kB file's 700 us. Falls back to the public constructor when this xarray lacks
    either or a size does not agree (the result is the same: ``tests/io``).
    """
    sizes: dict[str, int] = {}
    agree = True
    for var in (*variables.values(), *coords.values()):
        for dim, size in zip(var.dims, var.shape, strict=True):
            agree = agree and sizes.setdefault(dim, size) == size
    construct = getattr(xr.Dataset, "_construct_direct", None)
    try:
        from xarray.core.indexes import PandasIndex
    except ImportError:
        construct = None
    if construct is None or not agree or set(sizes) != {"ray", "range"}:
        return xr.Dataset(variables, coords=coords, attrs=attrs)
    ranges = coords["range"]
    index = PandasIndex(pd.Index(ranges.values, name="range"), "range")
    indexed = dict(coords, range=index.create_variables({"range": ranges})["range"])
    return construct(
        {**variables, **indexed},
        set(coords),
        sizes,
        attrs=attrs,
        indexes={"range": index},
    )


# --------------------------------------------------------------------------------------
# writer
# --------------------------------------------------------------------------------------


def _beta_strings(beta: np.ndarray) -> np.ndarray:
    """Backscatter as the instrument prints it: ``1.569249E-6`` (no exponent padding).

    Each distinct value is formatted once (a simulated file holds one).
    """
    unique, inverse = np.unique(np.asarray(beta, dtype=np.float64), return_inverse=True)
    s = np.char.mod("%.6E", unique)
    s = np.char.replace(s, "E+0", "E")
    s = np.char.replace(s, "E+", "E")
    s = np.char.replace(s, "E-0", "E-")
    return s[inverse].reshape(np.shape(beta))


def _data_lines(ray: list[str], columns: list[np.ndarray], formats: list[str]) -> str:
    """The ray and gate lines of a file, CRLF after each, by one ``%`` of the whole block.

    A gate line is the gate index (``%3d``) then the ``columns`` (rays x gates) with
    ``formats``, as ``np.char.mod`` of each field would give it. The block's format is
    built once per file with the gate indices, and every column that holds one value
    in the whole file (a simulated SNR or backscatter), written into it.
    """
    n_rays, n_gates = columns[0].shape
    fields, varying = "", []
    for column, fmt in zip(columns, formats, strict=True):
        first = column.flat[0]
        if np.all(column == first):
            fields += " " + (fmt % first).replace("%", "%%")
        else:
            fields += " " + fmt
            varying.append(column)
    block = "%s\r\n" + "".join(f"{g:3d}{fields}\r\n" for g in range(n_gates))
    table = np.empty((n_rays, 1 + n_gates * len(varying)), dtype=object)
    table[:, 0] = ray
    if varying:
        values = np.empty((n_rays, n_gates, len(varying)), dtype=object)
        for k, column in enumerate(varying):
            values[:, :, k] = column
        table[:, 1:] = values.reshape(n_rays, -1)
    return (block * n_rays) % tuple(table.ravel().tolist())


def hpl_text(ds: xr.Dataset, filename: str) -> str:
    """The ``.hpl`` text (CRLF line ends) of a canonical scan dataset.

    Parameters
    ----------
    ds : xarray.Dataset
        Canonical scan dataset; ``range`` must be (gate + 0.5) x ``gate_length_m``.
    filename : str
        Name written on the ``Filename:`` line.

    Raises
    ------
    CwprocError
        The range grid is not the Stream Line grid, there are no rays, or a value is
        not finite (the format has no fill value).
    """
    n_rays = int(ds.sizes["ray"])
    n_gates = int(ds.sizes["range"])
    if n_rays == 0:
        raise CwprocError(f"write_hpl {filename}: the dataset has no rays")
    gate_length, times = _writable(ds, filename)
    day = times.min().astype("datetime64[D]")
    hours = (times - day.astype("datetime64[us]")).astype(np.int64) / 3.6e9
    az = np.asarray(ds["azimuth"].values, dtype=np.float64)
    el = np.asarray(ds["elevation"].values, dtype=np.float64)
    has_pr = "pitch" in ds and "roll" in ds
    has_sw = "spectral_width" in ds
    header = _hpl_header(ds, filename, times[0], gate_length, has_pr, has_sw)
    ray = np.char.add(np.char.mod("%.8f", hours), np.char.mod(" %6.2f", az))
    ray = np.char.add(ray, np.char.mod(" %6.2f", el))
    if has_pr:
        ray = np.char.add(ray, np.char.mod(" %.2f", ds["pitch"].values))
        ray = np.char.add(ray, np.char.mod(" %.2f", ds["roll"].values))
    beta = ds["beta"].values if "beta" in ds else np.zeros((n_rays, n_gates))
    columns = [ds["radial_velocity"].values, ds["snr"].values + 1.0, _beta_strings(beta)]
    formats = ["%.4f", "%.6f", "%12s"]
    if has_sw:
        columns.append(ds["spectral_width"].values)
        formats.append("%.4f ")
    return "\r\n".join(header) + "\r\n" + _data_lines(ray.tolist(), columns, formats)


def _writable(ds: xr.Dataset, filename: str) -> tuple[float, np.ndarray]:
    """The gate length (m) and ray times (datetime64[us]) of a dataset the ``.hpl``
    format can hold.

    Raises
    ------
    CwprocError
        The range grid is not the Stream Line grid, or a value is not finite.
    """
    n_gates = int(ds.sizes["range"])
    ranges = np.asarray(ds["range"].values, dtype=np.float64)
    gate_length = float(ds.attrs.get("gate_length_m", 2.0 * ranges[0]))
    if not np.allclose(ranges, (np.arange(n_gates) + 0.5) * gate_length, rtol=0, atol=1e-6):
        raise CwprocError(
            f"write_hpl {filename}: range is not (gate + 0.5) x gate length "
            f"{gate_length} m, the Stream Line grid"
        )
    for name in (
        "radial_velocity",
        "snr",
        "beta",
        "spectral_width",
        "pitch",
        "roll",
        "azimuth",
        "elevation",
    ):
        if name in ds.variables and not np.isfinite(ds[name].values).all():
            raise CwprocError(
                f"write_hpl {filename}: {name} has non-finite values; the .hpl format has "
                "no fill value"
            )
    times = ds["time"].values.astype("datetime64[us]")
    if np.isnat(times).any():
        raise CwprocError(f"write_hpl {filename}: time has missing values")
    return gate_length, times


def _hpl_header(
    ds: xr.Dataset,
    filename: str,
    start_time: np.datetime64,
    gate_length: float,
    has_pr: bool,
    has_sw: bool,
) -> list[str]:
    """The 17 header lines of the ``.hpl`` file of ``ds`` (``has_pr``: pitch and roll on
    the ray lines; ``has_sw``: spectral width on the gate lines)."""
    n_rays = int(ds.sizes["ray"])
    n_gates = int(ds.sizes["range"])
    focus = float(ds.attrs.get("focus_range_m", float("inf")))
    focus_text = str(FOCUS_INFINITY) if not np.isfinite(focus) else f"{focus:g}"
    start = np.datetime_as_string(start_time, unit="ms")
    start_text = start[:10].replace("-", "") + " " + start[11:22]
    scan_type = str(ds.attrs.get("scan_type", "VAD"))
    which = "Altitude" if scan_type.startswith("Stare") else "Range"
    res = float(ds.attrs.get("velocity_resolution_m_s", 0.0382))
    spectral = ds.attrs.get("instrument_spectral_width_m_s")
    return [
        f"Filename:\t{filename}",
        f"System ID:\t{ds.attrs.get('system_id', '0')}",
        f"Number of gates:\t{n_gates}",
        f"Range gate length (m):\t{gate_length:.1f}",
        f"Gate length (pts):\t{int(ds.attrs.get('points_per_gate', round(gate_length / 3)))}",
        f"Pulses/ray:\t{int(ds.attrs.get('pulses_per_ray', 10000))}",
        f"No. of rays in file:\t{n_rays}",
        f"Scan type:\t{scan_type}",
        f"Focus range:\t{focus_text}",
        f"Start time:\t{start_text}",
        f"Resolution (m/s):\t{res:g}",
        f"{which} of measurement (center of gate) = (range gate + 0.5) * Gate length",
        "Data line 1: Decimal time (hours)  Azimuth (degrees)  Elevation (degrees)"
        + (" Pitch (degrees) Roll (degrees)" if has_pr else ""),
        "f9.6,1x,f6.2,1x,f6.2",
        "Data line 2: Range Gate  Doppler (m/s)  Intensity (SNR + 1)  Beta (m-1 sr-1)"
        + (" Spectral Width" if has_sw else ""),
        "i3,1x,f6.4,1x,f8.6,1x,e12.6" + (",1x,f6.4" if has_sw else "") + " - repeat for no. gates",
        "****" + (f" Instrument spectral width = {float(spectral):.6f}" if spectral else ""),
    ]


def write_hpl(ds: xr.Dataset, path: str | os.PathLike) -> Path:
    """Write a canonical scan dataset as a Stream Line ``.hpl`` file.

    The layout is the instrument's: 17 header lines, CRLF line ends, ray lines
    ``hours az el [pitch roll]`` with 8-decimal hours, gate lines
    ``i3 doppler intensity beta [spectral_width]`` with the backscatter right-aligned
    in 12 characters (two spaces before a positive value, one before a negative one).
    Times are written as decimal hours since 00:00 of the first ray's day (hours
    >= 24 after midnight).

    Parameters
    ----------
    ds : xarray.Dataset
        Canonical scan dataset (``snr`` is written as intensity = snr + 1).
    path : path-like
        Output file; its name goes on the ``Filename:`` line.

    Returns
    -------
    pathlib.Path
        The path written (through a temporary file renamed into place, so a killed
        run leaves no half-written file).
    """
    path = Path(path)
    data = hpl_text(ds, path.name).encode("ascii")
    try:
        write_bytes_atomic(path, data)
    except OSError as exc:
        raise CwprocError(f"write_hpl {path}: cannot write: {exc.strerror or exc}") from None
    return path
