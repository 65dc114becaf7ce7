"""Halo Photonics Stream Line ``.hpl`` files: many files (a day of scans) at once.

:func:`read_hpl_files` reads the day in two passes. The first reads each file's header
and counts its data lines, so that the rays of the whole record are known before any
number is parsed; the second parses one file at a time (:mod:`cwproc.io.halo_body`)
straight into the record's preallocated arrays. A file whose body is off in any way
sends the whole day to :func:`cwproc.io.halo.read_hpl` file by file, which names the
problem.
"""

from __future__ import annotations

import functools
import hashlib
import io
import os
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
import xarray as xr

from cwproc.errors import InputFileError
from cwproc.io.halo import (
    decimal_hours_to_time,
    read_header_body_offset,
    read_hpl,
)
from cwproc.io.halo_body import (
    SPACE_FIELDS,
    content_end,
    fields_of_row,
    float_column,
    read_body_table,
    single_space_ok,
    structure_problem,
)
from cwproc.io.halo_header import HplHeader, parse_hpl_header
from cwproc.io.hpl_attrs import bad_ray, check_no_options, scan_attrs
from cwproc.io.identity import FileIdentity
from cwproc.io.scan_join import concat_scans, joined_attrs, time_sorted_scans
from cwproc.physics.geometry import normalise_pointing
from cwproc.physics.scan_numbering import scan_indices_of_runs

try:  # the optional compiled tokenizer (setup.py)
    from cwproc.io import _hpltok
except ImportError:
    _hpltok = None

#: data lines joined for one call of the pandas tokenizer (bytes), used only when the
#: compiled tokenizer is not built: large enough to amortise pandas' cost per call
_BATCH_BYTES = 16 << 20


@dataclass(frozen=True)
class _FilePlan:
    """What the first pass learns of a file: header, where its data lines are, how many."""

    path: Path
    header: HplHeader
    #: byte offset of the data lines in the file
    offset: int
    #: the data lines are the first ``end`` bytes from ``offset`` (no final line end)
    end: int
    #: line feeds + 1, or CRs + 1 when there is no LF: the number of data lines when
    #: lines end in LF, CRLF or CR alone (a file that mixes lone CR with LF parses to
    #: another count and takes the reference path)
    n_lines: int
    #: fields of the first ray line and of the first gate line (3 and 4 when absent)
    fields: tuple[int, int] = (3, 4)
    #: the bytes of the file as this pass read them, when its checksum was asked for
    #: (hashed when :attr:`sha256` is first read)
    read: _ReadBytes | None = field(default=None, compare=False, repr=False)
    #: the data lines as this pass read them, when kept for the parse (taken by it)
    held: list[bytes] = field(default_factory=list, compare=False, repr=False)

    @functools.cached_property
    def sha256(self) -> str | None:
        """SHA-256 (hex) of the file as this pass read it (None: not asked for).

        Computed where it is first asked for, from the bytes the pass read (kept until
        then): a streamed day takes it in the reading thread once the file is parsed
        (:func:`cwproc.pipeline.stream_read.read_planned_chunk`), beside the numerical
        work of the caller's thread (``hashlib`` releases the GIL).
        """
        return None if self.read is None else self.read.hexdigest()


class _ReadBytes:
    """The pieces of a file as read, kept for its SHA-256 (:attr:`_FilePlan.sha256`).

    Takes the place of a :mod:`hashlib` object in
    :func:`cwproc.io.halo.read_header_body_offset`: ``update`` keeps a reference to
    each piece (no copy), and :meth:`hexdigest` hashes them once, then drops them.
    """

    def __init__(self) -> None:
        self._pieces: list[bytes | memoryview] = []

    def update(self, data: bytes | memoryview) -> None:
        self._pieces.append(data)

    def hexdigest(self) -> str:
        digest = hashlib.sha256()
        for piece in self._pieces:
            digest.update(piece)
        self._pieces = []
        return digest.hexdigest()


def _plan_file(
    path: Path,
    checksum: bool = False,
    keep: bool = False,
    known: tuple[HplHeader, int] | None = None,
) -> _FilePlan | None:
    """Header and line count of a file (and with ``checksum`` its SHA-256, taken by the
    same read), or ``None`` when anything is off (no raise). With ``keep``, the data
    lines read are kept for the parse (:func:`_data_lines`), which then does not read
    the file again. ``known``: the header and data offset an earlier read of the file
    found (not parsed again)."""
    read = _ReadBytes() if checksum else None
    try:
        if known is not None:
            header, known_offset = known
            _, body, offset = read_header_body_offset(path, read, known_offset)
        else:
            lines, body, offset = read_header_body_offset(path, read)
            header = parse_hpl_header(path, lines)
    except InputFileError:
        return None
    end = content_end(body)
    if end == 0 or body.find(b"\x00", 0, end) >= 0:
        return None
    line_ends = _count_byte(body, end, b"\n") or _count_byte(body, end, b"\r")
    first = body[:4096].lstrip(b"\r\n").splitlines()
    fields = (
        len(first[0].split()) if first else 3,
        len(first[1].split()) if len(first) > 1 else 4,
    )
    held = [body] if keep else []
    return _FilePlan(path, header, offset, end, line_ends + 1, fields, read, held)


def _count_byte(data: bytes, end: int, byte: bytes) -> int:
    """How often ``byte`` occurs in the first ``end`` bytes of ``data`` (``bytes.count``
    compares one byte at a time; ``memchr`` in the compiled tokenizer, else a vectorised
    compare, is about 4 times faster; the compiled count takes the GIL back once)."""
    counter = getattr(_hpltok, "count_byte", None)
    if counter is not None:
        return counter(data, end, byte[0])
    values = np.frombuffer(data, dtype=np.uint8, count=end)
    return int(np.count_nonzero(values == byte[0]))


def _same_layout(first: HplHeader, plan: _FilePlan) -> bool:
    """Whether a file can join the first one: same gates, range grid, system, whole rays."""
    header = plan.header
    return (
        header.n_gates == first.n_gates
        and header.gate_length_m == first.gate_length_m
        and header.range_divisor == first.range_divisor
        and header.range_step_m == first.range_step_m
        and header.system_id == first.system_id
        and plan.n_lines % (first.n_gates + 1) == 0
    )


def _plan(paths: list[Path]) -> list[_FilePlan] | None:
    """The first pass over every file (nothing kept but the plans); ``None`` if off."""
    plans: list[_FilePlan] = []
    for path in paths:
        plan = _plan_file(path)
        if plan is None or not _same_layout((plans[0] if plans else plan).header, plan):
            return None
        plans.append(plan)
    return plans


def _data_lines(plan: _FilePlan) -> bytes | None:
    """The data lines of a planned file: those the plan kept (handed over once), else
    read again; ``None`` if the file changed."""
    if plan.held:
        return plan.held.pop()
    try:
        with plan.path.open("rb") as f:
            f.seek(plan.offset)
            body = f.read()
    except OSError:
        return None
    return body if content_end(body) == plan.end else None


class _JoinedBodies(io.RawIOBase):
    """A read-only binary file over several files' data lines joined by CRLF.

    Serves the pandas tokenizer's reads from the files' own buffers, so that a batch
    of files is never copied into one joined buffer.
    """

    def __init__(self, pieces: list[memoryview]) -> None:
        super().__init__()
        self._pieces: list[memoryview] = []
        for piece in pieces:
            if self._pieces:
                self._pieces.append(memoryview(b"\r\n"))
            self._pieces.append(piece)
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


def _groups(plans: list[_FilePlan]) -> Iterator[list[_FilePlan]]:
    """The files parsed together: one by one with the compiled tokenizer, else batches
    of about ``_BATCH_BYTES`` of data lines for the pandas tokenizer."""
    if _hpltok is not None:
        yield from ([plan] for plan in plans)
        return
    group: list[_FilePlan] = []
    size = 0
    for plan in plans:
        if group and size + plan.end > _BATCH_BYTES:
            yield group
            group, size = [], 0
        group.append(plan)
        size += plan.end
    if group:
        yield group


def _group_columns(group: list[_FilePlan], n_gates: int) -> list[np.ndarray] | None:
    """The 5 columns of a group's data lines; ``None`` unless every ray block is whole
    and the line counts are those of the plans."""
    n_lines = sum(plan.n_lines for plan in group)
    bodies = [_data_lines(plan) for plan in group]
    if any(body is None for body in bodies):
        return None
    pieces = [memoryview(body)[: plan.end] for body, plan in zip(bodies, group, strict=True)]
    if _hpltok is not None:
        (piece,) = pieces
        if hasattr(_hpltok, "tokenize_lines"):  # the plan counted the lines: not again
            values, got, bad_line = _hpltok.tokenize_lines(piece, 5, n_lines)
        else:  # an extension built before tokenize_lines
            values, got, bad_line = _hpltok.tokenize(piece, 5)
        if bad_line >= 0 or got != n_lines:
            return None
        table = np.frombuffer(values, dtype=np.float64).reshape(n_lines, 5)
        columns = [table[:, j] for j in range(5)]
    else:
        if not all(single_space_ok(bytes(piece)) for piece in pieces):
            return None
        try:
            frame = read_body_table(_JoinedBodies(pieces), single_space=True)
        except (pd.errors.ParserError, ValueError, UnicodeDecodeError, pd.errors.EmptyDataError):
            return None
        if frame.shape[1] != SPACE_FIELDS or len(frame) != n_lines:
            return None
        columns = [float_column(frame[name]) for name in frame.columns]
        if not np.isnan(columns[5]).all():
            return None
        columns = columns[:5]
    return None if structure_problem(columns, n_gates) is not None else columns


class _Record:
    """The arrays of the whole record, allocated once and filled group by group.

    ``gates``: ``radial_velocity``, ``snr`` (intensity - 1), ``beta`` and, with 5-field
    gate lines, ``spectral_width``, each (ray, gate); ``per_ray``: the ray lines'
    fields (decimal hours, azimuth, elevation and, with 5-field ray lines, pitch and
    roll); ``time`` (datetime64[ns]). Rays are in the order of the files.
    """

    def __init__(self, n_rays: int, n_gates: int, layout: tuple[int, int]) -> None:
        ray_fields, gate_fields = layout
        names = ["radial_velocity", "snr", "beta"]
        if gate_fields == 5:
            names.append("spectral_width")
        self.layout = layout
        self.gates = {name: np.empty((n_rays, n_gates), dtype=np.float64) for name in names}
        self.per_ray = [np.empty(n_rays, dtype=np.float64) for _ in range(ray_fields)]
        self.time = np.empty(n_rays, dtype="datetime64[ns]")
        self.filled = 0

    def add(self, group: list[_FilePlan], columns: list[np.ndarray], n_gates: int) -> None:
        """Copy a group's parsed columns into the next rays (its layout is the record's)."""
        block = n_gates + 1
        grids = [col.reshape(-1, block) for col in columns]
        start, stop = self.filled, self.filled + grids[0].shape[0]
        for j, name in enumerate(self.gates, start=1):
            if name == "snr":
                np.subtract(grids[j][:, 1:], 1.0, out=self.gates[name][start:stop])
            else:
                self.gates[name][start:stop] = grids[j][:, 1:]
        for j, values in enumerate(self.per_ray):
            values[start:stop] = grids[j][:, 0]
        first = start
        for plan in group:
            last = first + plan.n_lines // block
            self.time[first:last] = decimal_hours_to_time(
                self.per_ray[0][first:last], plan.header.start_time
            )
            first = last
        self.filled = stop


def _fill(plans: list[_FilePlan]) -> _Record | None:
    """The second pass: every group parsed into the record; ``None`` on any damage or
    a layout unlike the first file's (e.g. pitch and roll in some files only)."""
    n_gates = plans[0].header.n_gates
    n_rays = sum(plan.n_lines for plan in plans) // (n_gates + 1)
    record: _Record | None = None
    for group in _groups(plans):
        columns = _group_columns(group, n_gates)
        if columns is None:
            return None
        layout = (fields_of_row(columns, 0), fields_of_row(columns, 1))
        if record is None:
            record = _Record(n_rays, n_gates, layout)
        elif layout != record.layout:
            return None
        record.add(group, columns, n_gates)
    return record


def _placement(plans: list[_FilePlan]) -> tuple[list[_FilePlan], np.ndarray | None]:
    """The files in order of their header's start time, and the position of each of
    their rays in the given order (``None`` when the given order is kept).

    Files given in any order (a directory listing) then fill the record in time order,
    so that it needs no reordering unless the files overlap in time.
    """
    index = sorted(range(len(plans)), key=lambda i: plans[i].header.start_time)
    if index == list(range(len(plans))):
        return plans, None
    block = plans[0].header.n_gates + 1
    rays = [plan.n_lines // block for plan in plans]
    starts = np.concatenate([[0], np.cumsum(rays)])
    origin = np.concatenate([np.arange(starts[i], starts[i] + rays[i]) for i in index])
    return [plans[i] for i in index], origin


def _read_together(paths: list[Path]) -> xr.Dataset | None:
    """The fast path of :func:`read_hpl_files`, or ``None`` to take the reference path.

    Memory: the record's arrays, one file's data lines and their parsed numbers, and,
    only when files overlap in time (rays out of time order or times repeated), one
    reordered variable (:func:`cwproc.io.scan_join.time_sorted_scans`).
    """
    plans = _plan(paths)
    if not plans:
        return None
    return _read_plans(plans, paths)


def _read_plans(plans: list[_FilePlan], paths: list[Path]) -> xr.Dataset | None:
    """The record of planned files (the second pass of :func:`_read_together`)."""
    placed, origin = _placement(plans)
    record = _fill(placed)
    if record is None:
        return None
    per_ray = record.per_ray
    if bad_ray(np.column_stack(per_ray[:3])) is not None:
        return None
    azimuth, elevation = normalise_pointing(per_ray[1], per_ray[2])
    variables = {name: (("ray", "range"), values, {}) for name, values in record.gates.items()}
    if len(per_ray) == 5:
        variables["pitch"] = (("ray",), per_ray[3], {})
        variables["roll"] = (("ray",), per_ray[4], {})
    first = plans[0].header
    scan_types = [plan.header.scan_type for plan in plans]
    attrs = joined_attrs(scan_attrs(paths[0], first), [path.name for path in paths], scan_types)
    time = record.time
    del record, per_ray  # the record's arrays now live in ``variables`` alone
    return time_sorted_scans(
        variables,
        fixed={},
        time=time,
        azimuth=azimuth,
        elevation=elevation,
        ranges=first.gate_ranges(),
        attrs=attrs,
        coord_attrs={},
        origin=origin,
    )


def read_hpl_files(paths: list[str | os.PathLike], **options: object) -> xr.Dataset:
    """Several ``.hpl`` files (e.g. a day of VAD scans) as one scan dataset.

    The result is exactly ``concat_scans([read_hpl(p) for p in paths])`` (rays sorted
    by time, repeated times dropped, ``scan`` assigned over the whole record), built
    without one dataset per file. When every file has the same gates, range grid,
    system id and field layout, a first pass reads the headers and counts the data
    lines (``Number of gates`` + 1 per ray), the record's arrays are allocated once,
    and a second pass parses each file in order of its header's start time (the
    compiled tokenizer; without it, batches of about 16 MB through the pandas
    tokenizer) and copies its numbers into place. The peak memory is the arrays of the
    record plus one file's data (one batch without the compiled tokenizer) and, only
    when files overlap in time (rays out of time order or times repeated), one
    reordered variable. Measured on a synthetic day of 720 files
    (``benchmarks/bench_read_hpl.py``): 1.05 times the dataset above the imports, in
    time order or reversed (the reference path: 2.1 times). Anything else (different
    layouts, any damage, lone CR and LF line ends in one file) takes the reference
    path file by file, which raises the exact error of the first bad file.

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
        :func:`cwproc.io.scan_join.concat_scans`).
    """
    check_no_options(options)
    paths = [Path(p) for p in paths]
    if paths:
        together = _read_together(paths)
        if together is not None:
            return together
    return concat_scans([read_hpl(path) for path in paths])


def plan_hpl_file(
    path: str | os.PathLike,
    checksum: bool = False,
    keep_body: bool = False,
    identity: FileIdentity | None = None,
) -> _FilePlan | None:
    """A file's header and data line count (the first pass of :func:`read_hpl_files`),
    or ``None`` when anything is off (its error is :func:`read_hpl`'s to name).

    With ``checksum``, the plan also holds the SHA-256 of the file, fed by the same read
    (``sha256``): the checksum of a file identified by its header alone, taken without
    reading the file once more. With ``keep_body``, the plan keeps the data lines it
    read until :func:`read_hpl_run` parses them (one read of the file in all; the
    caller holds a chunk's text in the meantime). With ``identity`` (the file's
    :func:`cwproc.io.halo.read_hpl_identity`, the file unchanged since: the caller
    checks its signature), its header is taken from there, not split and parsed again.
    """
    header = getattr(identity, "header", None)
    offset = getattr(identity, "offset", None)
    known = (header, offset) if isinstance(header, HplHeader) and offset is not None else None
    return _plan_file(Path(path), checksum, keep_body, known)


def planned_bytes(plan: _FilePlan) -> int:
    """Bytes of the dataset :func:`read_hpl` makes of a planned file (``nbytes``).

    Gate variables (``Number of gates`` float64 values a ray each: 3, or 4 with the
    spectral width) and per-ray ones (time, azimuth, elevation, scan and, with 5-field
    ray lines, pitch and roll; 8 bytes each), from the fields of the first ray and gate
    lines, plus the range grid.
    """
    ray_fields, gate_fields = plan.fields
    n_gates = plan.header.n_gates
    n_rays = plan.n_lines // (n_gates + 1)
    per_ray = 4 + (2 if ray_fields == 5 else 0)
    return 8 * (n_rays * (n_gates * (gate_fields - 1) + per_ray) + n_gates)


@dataclass(frozen=True)
class HplFilePart:
    """One file of :func:`read_hpl_run`: what :func:`read_hpl` would say of it alone."""

    #: the file's attributes and first ray time (those of its :func:`read_hpl` dataset)
    identity: FileIdentity
    #: its rays: ``start:stop`` of the joined dataset
    start: int
    stop: int
    #: scan index of each of its rays, numbered within the file as :func:`read_hpl` does
    scan: np.ndarray


def read_hpl_run(plans: list[_FilePlan]) -> tuple[xr.Dataset, list[HplFilePart]] | None:
    """Planned files that follow each other in time, read into one dataset at once.

    The dataset is :func:`read_hpl_files` of the files (``concat_scans`` of their
    :func:`read_hpl` datasets); each file's rays are a contiguous run of it, in the
    given order, and its :class:`HplFilePart` holds what its own dataset would have
    said (attributes, first time, scan numbering). ``None`` (read them one by one)
    on any damage, layouts that differ, or rays that do not run strictly forward in
    time through the files in the given order.
    """
    if not plans or not all(_same_layout(plans[0].header, plan) for plan in plans):
        return None
    starts = [plan.header.start_time for plan in plans]
    if starts != sorted(starts):
        return None
    ds = _read_plans(plans, [plan.path for plan in plans])
    if ds is None:
        return None
    block = plans[0].header.n_gates + 1
    bounds = np.concatenate([[0], np.cumsum([plan.n_lines // block for plan in plans])])
    time = ds.variables["time"].values
    if time.size != bounds[-1] or not bool(np.all(time[1:] > time[:-1])):
        return None
    azimuth = ds.variables["azimuth"].values
    elevation = ds.variables["elevation"].values
    scans = scan_indices_of_runs(
        time, azimuth, elevation, bounds, [plan.header.scan_type for plan in plans]
    )
    parts = []
    for plan, a, b, scan in zip(plans, bounds[:-1], bounds[1:], scans, strict=True):
        a, b = int(a), int(b)
        identity = FileIdentity(scan_attrs(plan.path, plan.header), time[a : a + 1].copy())
        parts.append(HplFilePart(identity, a, b, scan))
    return ds, parts
