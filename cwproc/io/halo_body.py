"""Halo Photonics Stream Line ``.hpl`` files: tokenising the data lines.

After the header, one block per ray: a *ray line* (decimal hours, azimuth, elevation
and, on most instruments, pitch and roll) and ``Number of gates`` *gate lines* (gate
index, Doppler velocity, intensity, attenuated backscatter and optionally the spectral
width; ``real_data/FORMATS.md`` section 1). :func:`tokenize_body` parses a whole body with
one call of the compiled tokenizer (``_hpltok``, built by ``setup.py``) or the pandas C
tokenizer, :func:`structure_problem` checks the block structure (in one compiled pass
over the tokenizer's table, else with array operations), and only when a check fails
:func:`diagnose` walks the offending ray block line by line to name the first bad line.
"""

from __future__ import annotations

import csv
import io
import itertools
import os
import re
import warnings
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pandas as pd

from cwproc.errors import InputFileError
from cwproc.io.halo_header import HEADER_LINES

try:  # the optional compiled tokenizer (setup.py); pandas does the same work without it
    from cwproc.io import _hpltok
except ImportError:
    _hpltok = None

#: bodies larger than this (bytes) are parsed in parallel chunks (not smaller: batch runs
#: already read several files at once, and threads would oversubscribe the cores)
_PARALLEL_BYTES = 8 << 20


def content_end(raw: bytes, start: int = 0) -> int:
    """Offset just after the last non-blank byte of ``raw[start:]`` (``start`` if none).

    Equivalent to ``start + len(raw[start:].rstrip())`` but only looks at the end of
    the data (doubling tails), so the body is not copied twice to drop a final newline.
    """
    end = len(raw)
    tail = 64
    while end > start:
        lo = max(start, end - tail)
        kept = len(raw[lo:end].rstrip())
        if kept:
            return lo + kept
        end = lo
        tail *= 2
    return start


#: fields per line that the single-space tokenizer keeps: 5 and the empty field after a
#: trailing space (a sixth number is an error, found by :func:`tokenize_body`)
SPACE_FIELDS = 6


def read_body_table(body: bytes | io.RawIOBase, *, single_space: bool) -> pd.DataFrame:
    """Parse body lines with the pandas C tokenizer (5 or, see below, 6 columns).

    ``body`` is the data or a binary file object that reads it.

    ``single_space``: the body has no TAB, so fields are split at single spaces with
    ``skipinitialspace`` (leading, repeated and trailing spaces as in the instrument
    files; about 15 % faster than the regular-expression separator ``\\s+``, which
    pandas maps to its whitespace tokenizer). A trailing space gives an empty sixth
    field. Otherwise ``\\s+`` with 5 columns.
    """
    layout = (
        {"sep": " ", "skipinitialspace": True, "names": range(SPACE_FIELDS)}
        if single_space
        else {"sep": r"\s+", "names": range(5)}
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return pd.read_csv(
            io.BytesIO(body) if isinstance(body, bytes) else body,
            header=None,
            engine="c",
            skip_blank_lines=False,
            quoting=csv.QUOTE_NONE,
            # bytes go to the tokenizer as they are (a non-UTF-8 encoding would make
            # pandas decode and re-encode the whole body); a field that is not valid
            # UTF-8 stays a string (surrogate escapes) and so becomes +inf, no number
            encoding_errors="surrogateescape",
            keep_default_na=False,
            na_values=[""],
            low_memory=False,
            **layout,
        )


def _chunks(body: bytes, n_chunks: int) -> list[tuple[int, int]]:
    """Byte spans of ``body`` cut at line starts into about ``n_chunks`` equal parts."""
    if n_chunks <= 1 or b"\n" not in body:
        return [(0, len(body))]
    cuts = [0]
    for k in range(1, n_chunks):
        nl = body.find(b"\n", k * len(body) // n_chunks)
        if nl < 0 or nl + 1 >= len(body):
            break
        if nl + 1 > cuts[-1]:
            cuts.append(nl + 1)
    cuts.append(len(body))
    return list(itertools.pairwise(cuts))


def tokenize_body(
    path: str | os.PathLike, body: bytes, *, single_space: bool | None = None
) -> list[np.ndarray]:
    """The 5 fields of every body line as 5 float columns (NaN where a line is shorter).

    A field that is not a finite number (``abc``, ``nan``, ``inf``) is +inf, so that
    the structure check can tell it from a missing field; a line with more than 5
    fields raises here. The compiled tokenizer ``cwproc.io._hpltok`` does the work when
    it was built (``setup.py``: an optional extension; every value equals
    ``float(token)``, about twice the speed of pandas); otherwise the pandas C tokenizer
    (single-space separator when :func:`single_space_ok`, see :func:`read_body_table`); very
    large bodies are cut at line starts and parsed in threads (the tokenizer releases the
    GIL). The columns
    may be read-only or strided views (of one float table up to ``_TABLE_ROWS``
    lines, else of the parser's columns).
    """
    if _hpltok is not None:
        values, n_lines, bad_line = _hpltok.tokenize(body, 5)
        if bad_line < 0:  # else the pandas tokenizer below names the line and its fields
            table = np.frombuffer(values, dtype=np.float64).reshape(n_lines, 5)
            return [table[:, j] for j in range(5)]
    if single_space is None:
        single_space = single_space_ok(body)
    workers = min(os.cpu_count() or 1, max(1, len(body) // _PARALLEL_BYTES))
    spans = _chunks(body, workers)

    def parse(span: tuple[int, int]) -> pd.DataFrame:
        return read_body_table(body[span[0] : span[1]], single_space=single_space)

    try:
        if len(spans) == 1:
            frames = [read_body_table(body, single_space=single_space)]
        else:
            with ThreadPoolExecutor(len(spans)) as pool:
                frames = list(pool.map(parse, spans))
    except pd.errors.ParserError as exc:
        if single_space:  # name the line exactly as the whitespace tokenizer does
            return tokenize_body(path, body, single_space=False)
        m = re.search(r"Expected \d+ fields in line (\d+), saw (\d+)", str(exc))
        if m is None:
            raise InputFileError(
                path, f"cannot parse the data lines ({exc})", HEADER_LINES + 1
            ) from None
        # which chunk failed: re-parse the chunks one by one (error path only)
        for start, end in spans:
            try:
                read_body_table(body[start:end], single_space=False)
            except pd.errors.ParserError as chunk_exc:
                m = re.search(r"Expected \d+ fields in line (\d+), saw (\d+)", str(chunk_exc))
                if m is None:
                    break
                before = body.count(b"\n", 0, start)
                raise InputFileError(
                    path,
                    f"line has {m.group(2)} fields; ray lines have 3 or 5, gate lines 4 or 5",
                    HEADER_LINES + before + int(m.group(1)),
                ) from None
        raise InputFileError(
            path, f"cannot parse the data lines ({exc})", HEADER_LINES + 1
        ) from None
    except (ValueError, UnicodeDecodeError, pd.errors.EmptyDataError) as exc:
        raise InputFileError(
            path, f"cannot parse the data lines ({exc})", HEADER_LINES + 1
        ) from None
    if sum(len(frame) for frame in frames) <= _TABLE_ROWS:
        tables = [_float_table(frame) for frame in frames]
        table = tables[0] if len(tables) == 1 else np.concatenate(tables)
        columns = [table[:, j] for j in range(table.shape[1])]
    else:
        parts = [[float_column(frame[name]) for name in frame.columns] for frame in frames]
        columns = [p[0] if len(p) == 1 else np.concatenate(p) for p in zip(*parts, strict=True)]
    if len(columns) > 5 and not np.isnan(columns[5]).all():
        return tokenize_body(path, body, single_space=False)  # the reference names the line
    return columns[:5]


#: parsed tables up to this many lines become one float array (one call, one copy);
#: longer ones are taken column by column (no copy of the parser's columns)
_TABLE_ROWS = 100_000


def _float_table(frame: pd.DataFrame) -> np.ndarray:
    """The parsed lines as a float array (line, field); see :func:`float_column`.

    One copy of the parser's columns (measured: fewer page faults than keeping the
    columns, whose memory is then freed and reused at once).
    """
    if all(dtype.kind == "f" for dtype in frame.dtypes):
        return frame.to_numpy(dtype=np.float64)
    return np.column_stack([float_column(frame[name]) for name in frame.columns])


def float_column(col: pd.Series) -> np.ndarray:
    """A parsed column as float64; a field that is there but no number becomes +inf."""
    if col.dtype.kind in "fiu":
        return col.to_numpy(dtype=np.float64)
    numbers = pd.to_numeric(col, errors="coerce")
    values = numbers.to_numpy(dtype=np.float64, na_value=np.nan, copy=True)
    values[col.notna().to_numpy() & np.isnan(values)] = np.inf
    return values


def fields_of_row(columns: list[np.ndarray], row: int) -> int:
    """Number of leading finite fields of one body row (0 when there is no such row)."""
    if row >= columns[0].size:
        return 0
    count = 0
    for col in columns:
        if not np.isfinite(col[row]):
            break
        count += 1
    return count


def single_space_ok(body: bytes) -> bool:
    """Whether the single-space tokenizer applies: no TAB and no lone CR line end.

    (pandas' ``skipinitialspace`` takes the leading space of a line that follows a lone
    CR as a separator.)
    """
    if b"\t" in body:
        return False
    if b"\r" not in body:  # LF files: no CR at all (memchr, no numpy pass)
        return True
    data = np.frombuffer(body, dtype=np.uint8)
    follows = np.flatnonzero(data == 13) + 1
    return bool(follows[-1] < data.size and (data[follows] == 10).all())


def structure_problem(
    columns: list[np.ndarray], n_gates: int
) -> tuple[int, int, int | None, int | None] | None:
    """Where the ray/gate block structure of the parsed body breaks, or ``None``.

    Returns
    -------
    tuple or None
        ``(start_row, n_gates, ray_fields, gate_fields)``: the arguments after
        ``body`` of :func:`diagnose` for the ray block to walk (field counts ``None``
        when the first rows do not even say them); ``None`` when every block is whole.
    """
    ray_fields = fields_of_row(columns, 0)
    gate_fields = fields_of_row(columns, 1)
    if ray_fields not in (3, 5) or gate_fields not in (4, 5):
        return 0, n_gates, None, None
    block = n_gates + 1
    bad = first_bad_row(columns, n_gates, ray_fields, gate_fields)
    if bad >= 0:
        return (bad // block) * block, n_gates, ray_fields, gate_fields
    n_rows = columns[0].size
    if n_rows % block:
        return (n_rows // block) * block, n_gates, ray_fields, gate_fields
    return None


def first_bad_row(
    columns: list[np.ndarray], n_gates: int, ray_fields: int, gate_fields: int
) -> int:
    """Index of the first body row that breaks the ray/gate block structure, or -1.

    A row is good when exactly its first ``ray_fields`` (ray rows, every
    ``n_gates + 1``-th row) or ``gate_fields`` (gate rows) fields are present, all of them
    finite numbers (``+inf`` marks a field that is no number, see :func:`tokenize_body`),
    and, for a gate row, when its gate index equals its position in the block.
    Rows of an incomplete last block are checked as far as they go.

    Columns of the compiled tokenizer's table (:func:`_row_major_table`) are checked
    by its checker (``_hpltok.first_bad_row``) in one pass without the GIL; others by
    :func:`first_bad_row_of_columns`, the same result.
    """
    checker = getattr(_hpltok, "first_bad_row", None)
    table = _row_major_table(columns) if checker is not None else None
    if table is None:
        return first_bad_row_of_columns(columns, n_gates, ray_fields, gate_fields)
    return checker(table, table.shape[0], table.shape[1], n_gates, ray_fields, gate_fields)


def _row_major_table(columns: list[np.ndarray]) -> np.ndarray | None:
    """The float64 table (rows x columns, C order) whose columns ``columns`` are, as the
    compiled tokenizer's ``table[:, j]`` views are; None for columns laid out otherwise.

    Checked from the columns' own layout: every column float64 and of one length, with
    the stride of a table row, column ``j`` starting ``j`` values after the first.
    """
    k = len(columns)
    first = columns[0]
    if first.dtype != np.float64 or first.ndim != 1 or first.strides != (8 * k,):
        return None
    start = first.__array_interface__["data"][0]
    for j, col in enumerate(columns):
        if (
            col.dtype != np.float64
            or col.shape != first.shape
            or col.strides != first.strides
            or col.__array_interface__["data"][0] != start + 8 * j
        ):
            return None
    return np.lib.stride_tricks.as_strided(
        first, shape=(first.size, k), strides=(8 * k, 8), writeable=False
    )


def first_bad_row_of_columns(
    columns: list[np.ndarray], n_gates: int, ray_fields: int, gate_fields: int
) -> int:
    """:func:`first_bad_row` with array operations on the columns (any layout)."""
    n_rows = columns[0].size
    block = n_gates + 1
    n_blocks = -(-n_rows // block)
    pad = n_blocks * block - n_rows
    ok = np.ones((n_blocks, block), dtype=bool)
    index = np.arange(-1, n_gates, dtype=np.float64)
    for j, col in enumerate(columns):
        if pad:
            filler = np.where(j < gate_fields, 0.0, np.nan) * np.ones(pad)
            if j == 0:
                filler = np.tile(index, n_blocks)[n_rows:]
            col = np.concatenate([col, filler])
        grid = col.reshape(n_blocks, block)
        ok[:, 0] &= np.isfinite(grid[:, 0]) if j < ray_fields else np.isnan(grid[:, 0])
        gates = grid[:, 1:]
        ok[:, 1:] &= np.isfinite(gates) if j < gate_fields else np.isnan(gates)
        if j == 0:
            ok[:, 1:] &= gates == index[1:]
    bad = np.flatnonzero(~ok.ravel())
    return int(bad[0]) if bad.size else -1


_NUMBER = re.compile(rb"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")


def _is_number(token: bytes) -> bool:
    """Whether a token is a finite decimal number as the instrument writes them."""
    return _NUMBER.fullmatch(token) is not None and bool(np.isfinite(float(token)))


#: added to the error of a bad last line when the file does not end with a line end
_CUT_HINT = (
    "; the file ends inside this line: it was cut short (a broken copy, or the file of "
    "the current hour still being written)"
)


def diagnose(
    path: str | os.PathLike,
    body: bytes,
    start_row: int,
    n_gates: int,
    ray_fields: int | None,
    gate_fields: int | None,
) -> InputFileError:
    """Name the first bad line of the ray block that starts at body row ``start_row``.

    Only called when the vectorised structure check failed: walks one ray block
    (``n_gates + 1`` lines) and returns the error to raise. ``ray_fields`` and
    ``gate_fields`` are the field counts of the file (``None``: not known yet, 3 or 5
    and 4 or 5 are accepted).
    """
    lines = body.splitlines()
    block = n_gates + 1
    first = HEADER_LINES + 1  # file line number of body row 0
    ray_ok = (3, 5) if ray_fields is None else (ray_fields,)
    gate_ok = (4, 5) if gate_fields is None else (gate_fields,)
    cut_short = not body.endswith((b"\n", b"\r"))
    for row in range(start_row, min(start_row + block, len(lines))):
        line_no = first + row
        tokens = lines[row].split()
        pos = row - start_row
        # the last line of a file without a final line end: a file cut off mid-line
        cut = _CUT_HINT if cut_short and row == len(lines) - 1 else ""
        if not tokens:
            return InputFileError(path, "empty line inside the data", line_no)
        bad = [t for t in tokens if not _is_number(t)]
        if bad:
            token = bad[0].decode("latin-1")
            return InputFileError(path, f"field {token[:20]!r} is not a number{cut}", line_no)
        if pos == 0:
            problem = _ray_line_problem(tokens, row, n_gates, ray_ok, cut)
            if problem:
                return InputFileError(path, problem, line_no)
            continue
        problem = _gate_line_problem(tokens, pos - 1, n_gates, gate_ok, cut)
        if problem:
            return InputFileError(path, problem, line_no)
        if gate_fields is None:
            gate_ok = (len(tokens),)
        if ray_fields is None:
            ray_ok = (len(lines[start_row].split()),)
    n_rows = len(lines)
    if start_row + block > n_rows:
        got = n_rows - start_row - 1
        return InputFileError(
            path,
            f"last ray is truncated: {got} of {n_gates} gate lines after its ray line "
            "(file cut short, or Number of gates does not match the data)",
            first + start_row,
        )
    return InputFileError(path, "inconsistent ray block", first + start_row)


def _ray_line_problem(
    tokens: list[bytes], row: int, n_gates: int, ray_ok: tuple[int, ...], cut: str
) -> str:
    """What is wrong with the numbers ``tokens`` of body row ``row`` read as a ray line
    ('' when nothing); ``ray_ok``: the field counts accepted, ``cut``: a hint appended
    when the line is the cut last one."""
    if b"." not in tokens[0]:
        restart = (
            ": the gate index restarts without a ray line" if row and tokens[0] == b"0" else ""
        )
        return (
            f"expected a ray line (decimal time, azimuth, elevation) "
            f"{f'after {n_gates} gate lines ' if row else ''}but found gate index "
            f"{tokens[0].decode('latin-1')}{restart}"
        )
    if len(tokens) not in ray_ok:
        return f"ray line has {len(tokens)} fields, expected " + " or ".join(map(str, ray_ok)) + cut
    return ""


def _gate_line_problem(
    tokens: list[bytes], gate: int, n_gates: int, gate_ok: tuple[int, ...], cut: str
) -> str:
    """What is wrong with the numbers ``tokens`` read as the line of gate ``gate`` (''
    when nothing); ``gate_ok``: the field counts accepted, ``cut`` as for
    :func:`_ray_line_problem`."""
    if b"." in tokens[0] and len(tokens) in (3, 5):
        return f"ray line after only {gate} of {n_gates} gate lines (Number of gates: {n_gates})"
    if len(tokens) not in gate_ok:
        return (
            f"gate line has {len(tokens)} fields, expected " + " or ".join(map(str, gate_ok)) + cut
        )
    if b"." in tokens[0] or float(tokens[0]) != gate:
        index = tokens[0].decode("latin-1")
        hint = ": the gate index restarts without a ray line" if index == "0" else ""
        return f"gate index {index} where {gate} was expected{hint}"
    return ""
