"""Halo Photonics Stream Line ``.hpl`` files: many files (a day of scans) at once.

:func:`read_hpl_files` reads the files' headers, joins the bodies of files with the
same layout and parses each batch with one tokenizer call (:mod:`cwproc.io.halo_body`);
a file whose body is off in any way is read alone by :func:`cwproc.io.halo.read_hpl`,
which names the problem.
"""

from __future__ import annotations

import io
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import xarray as xr

from cwproc.errors import InputFileError
from cwproc.io.halo import (
    _attrs,
    _bad_ray,
    _check_options,
    decimal_hours_to_time,
    read_header_and_body,
    read_hpl,
)
from cwproc.io.halo_body import (
    _SPACE_FIELDS,
    _fields_of_row,
    _float_column,
    _hpltok,
    _read_table,
    content_end,
    line_ends,
    structure_problem,
)
from cwproc.io.halo_header import HplHeader, parse_header
from cwproc.io.scans import concat_scans, joined_attrs, time_sorted_scans
from cwproc.physics.geometry import normalise_pointing

#: bodies joined for one tokenizer call in :func:`read_hpl_files` (bytes): large enough
#: to amortise the per-call cost, small enough to bound the tokenizer's working memory
_BATCH_BYTES = 16 << 20


@dataclass(frozen=True)
class _Body:
    """One file's header and data lines, as :func:`read_hpl_files` needs them."""

    path: Path
    header: HplHeader
    #: the data lines are ``body[:end]`` (no final line end, no blank tail)
    body: bytes
    end: int
    n_lines: int
    single_space: bool


def _load_body(path: Path) -> _Body | None:
    """Header and body of a file, or ``None`` when anything is off (no raise)."""
    try:
        lines, body = read_header_and_body(path)
        header = parse_header(path, lines)
    except InputFileError:
        return None
    end = content_end(body)
    if end == 0 or body.find(b"\x00", 0, end) >= 0:
        return None
    n_lines, lone_cr = line_ends(memoryview(body)[:end])
    return _Body(
        path=path,
        header=header,
        body=body,
        end=end,
        n_lines=n_lines,
        single_space=not lone_cr and body.find(b"\t", 0, end) < 0,
    )


class _JoinedBodies(io.RawIOBase):
    """A read-only binary file over the data lines of several files joined by CRLF.

    Serves the tokenizer's reads from the files' own buffers, so that a day of files
    is never copied into one large joined buffer.
    """

    def __init__(self, bodies: list[_Body]) -> None:
        super().__init__()
        self._pieces: list[memoryview] = []
        for item in bodies:
            if self._pieces:
                self._pieces.append(memoryview(b"\r\n"))
            self._pieces.append(memoryview(item.body)[: item.end])
        self._index = 0
        self._offset = 0

    def readable(self) -> bool:
        return True

    def readinto(self, buffer: bytearray | memoryview) -> int:
        out = memoryview(buffer).cast("B")
        n = 0
        while n < len(out) and self._index < len(self._pieces):
            piece = self._pieces[self._index]
            take = min(len(out) - n, len(piece) - self._offset)
            out[n : n + take] = piece[self._offset : self._offset + take]
            n += take
            self._offset += take
            if self._offset == len(piece):
                self._index += 1
                self._offset = 0
        return n


def _batch_columns(batch: list[_Body], n_gates: int) -> list[np.ndarray] | None:
    """The 5 columns of a batch's bodies, parsed in one call; ``None`` if not whole."""
    if _hpltok is not None:
        tables = []
        for item in batch:
            values, n_lines, bad_line = _hpltok.tokenize(memoryview(item.body)[: item.end], 5)
            if bad_line >= 0 or n_lines != item.n_lines:
                return None
            tables.append(np.frombuffer(values, dtype=np.float64).reshape(n_lines, 5))
        table = tables[0] if len(tables) == 1 else np.concatenate(tables)
        columns = [table[:, j] for j in range(5)]
        return None if structure_problem(columns, n_gates) is not None else columns
    if not all(item.single_space for item in batch):
        return None
    try:
        frame = _read_table(_JoinedBodies(batch), single_space=True)
    except (pd.errors.ParserError, ValueError, UnicodeDecodeError, pd.errors.EmptyDataError):
        return None
    if frame.shape[1] != _SPACE_FIELDS or len(frame) != sum(item.n_lines for item in batch):
        return None
    columns = [_float_column(frame[name]) for name in frame.columns]
    if not np.isnan(columns[5]).all():
        return None
    columns = columns[:5]
    if structure_problem(columns, n_gates) is not None:
        return None
    return columns


def _same_layout(first: HplHeader, item: _Body) -> bool:
    """Whether a file can be parsed with the first one: same gates, range grid, system."""
    header = item.header
    return (
        header.n_gates == first.n_gates
        and header.gate_length_m == first.gate_length_m
        and header.range_divisor == first.range_divisor
        and header.range_step_m == first.range_step_m
        and header.system_id == first.system_id
        and item.n_lines % (first.n_gates + 1) == 0
    )


@dataclass(frozen=True)
class _BatchArrays:
    """The per-ray arrays of one batch of files (rays in file order)."""

    layout: tuple[int, int]  # fields of the ray lines and of the gate lines
    variables: dict[str, np.ndarray]  # canonical names, ray first
    time: np.ndarray
    azimuth: np.ndarray
    elevation: np.ndarray


def _batch_arrays(batch: list[_Body], n_gates: int) -> _BatchArrays | None:
    """Parse one batch and keep only its dataset arrays; ``None`` if anything is off."""
    columns = _batch_columns(batch, n_gates)
    if columns is None:
        return None
    ray_fields, gate_fields = _fields_of_row(columns, 0), _fields_of_row(columns, 1)
    block = n_gates + 1
    grids = [col.reshape(-1, block) for col in columns]
    rays = np.column_stack([g[:, 0] for g in grids])
    if _bad_ray(rays) is not None:
        return None
    counts = [item.n_lines // block for item in batch]
    ends = np.cumsum(counts)
    time = np.concatenate(
        [
            decimal_hours_to_time(rays[end - count : end, 0], item.header.start_time)
            for item, count, end in zip(batch, counts, ends, strict=True)
        ]
    )
    azimuth, elevation = normalise_pointing(rays[:, 1], rays[:, 2])
    variables = {
        "radial_velocity": np.ascontiguousarray(grids[1][:, 1:]),
        "snr": grids[2][:, 1:] - 1.0,
        "beta": np.ascontiguousarray(grids[3][:, 1:]),
    }
    if gate_fields == 5:
        variables["spectral_width"] = np.ascontiguousarray(grids[4][:, 1:])
    if ray_fields == 5:
        variables["pitch"] = rays[:, 3].copy()
        variables["roll"] = rays[:, 4].copy()
    return _BatchArrays((ray_fields, gate_fields), variables, time, azimuth, elevation)


def _add_batch(batch: list[_Body], n_gates: int, done: list[_BatchArrays]) -> bool:
    """Parse a batch onto ``done``; False on damage or a layout unlike the first batch's
    (e.g. pitch and roll in some files only)."""
    arrays = _batch_arrays(batch, n_gates)
    if arrays is None or (done and arrays.layout != done[0].layout):
        return False
    done.append(arrays)
    return True


def _read_together(paths: list[Path]) -> xr.Dataset | None:
    """The fast path of :func:`read_hpl_files`, or ``None`` to take the reference path.

    Files are read and parsed batch by batch (about ``_BATCH_BYTES`` of data each);
    only the dataset arrays of a batch are kept, so the peak memory is the result
    plus one batch.
    """
    first: HplHeader | None = None
    scan_types: list[str] = []
    done: list[_BatchArrays] = []
    batch: list[_Body] = []
    size = 0
    for path in paths:
        item = _load_body(path)
        if item is None:
            return None
        if first is None:
            first = item.header
        if not _same_layout(first, item):
            return None
        scan_types.append(item.header.scan_type)
        if batch and size + item.end > _BATCH_BYTES:
            if not _add_batch(batch, first.n_gates, done):
                return None
            batch, size = [], 0
        batch.append(item)
        size += item.end
    if first is None or not _add_batch(batch, first.n_gates, done):
        return None
    ray_range = ("ray", "range")
    variables = {
        name: (
            ray_range if values.ndim == 2 else ("ray",),
            np.concatenate([b.variables[name] for b in done]) if len(done) > 1 else values,
            {},
        )
        for name, values in done[0].variables.items()
    }
    attrs = joined_attrs(_attrs(paths[0], first), [path.name for path in paths], scan_types)
    return time_sorted_scans(
        variables,
        fixed={},
        time=np.concatenate([b.time for b in done]),
        azimuth=np.concatenate([b.azimuth for b in done]),
        elevation=np.concatenate([b.elevation for b in done]),
        ranges=first.gate_ranges(),
        attrs=attrs,
        coord_attrs={},
    )


def read_hpl_files(paths: list[str | os.PathLike], **options: object) -> xr.Dataset:
    """Several ``.hpl`` files (e.g. a day of VAD scans) as one scan dataset.

    The result is exactly ``concat_scans([read_hpl(p) for p in paths])`` (rays sorted
    by time, repeated times dropped, ``scan`` assigned over the whole record), built
    without one dataset per file. When every file has the same gates, range grid,
    system id and field layout, the files are read in batches of about 16 MB of data,
    each batch parsed by one tokenizer call (served from the files' buffers, no joined
    copy) and checked as a whole, and only its dataset arrays are kept (the peak
    memory is about that of the reference path). Anything else (different layouts,
    any damage) takes the reference path file by file, which raises the exact error
    of the first bad file. Measured on a synthetic day of 720 files
    (``benchmarks/bench_read_hpl.py``): 2-3 times faster than the reference path.

    Parameters
    ----------
    paths : list of path-like
        The files, in any order.
    **options
        ``[reader.hpl]`` table (the reader takes no options; any key raises
        :class:`cwproc.errors.ConfigError`).

    Raises
    ------
    InputFileError
        A file is damaged (as :func:`read_hpl`).
    CwprocError
        No files, or files that cannot be concatenated (as
        :func:`cwproc.io.scans.concat_scans`).
    """
    _check_options(options)
    paths = [Path(p) for p in paths]
    if paths:
        together = _read_together(paths)
        if together is not None:
            return together
    return concat_scans([read_hpl(path) for path in paths])
