"""A day of scans processed chunk by chunk in bounded memory (issue 15.3).

The files of a scan unit are taken in time order and joined into chunks of about
``STREAM_CHUNK_BYTES`` (``.hpl`` files parsed straight into the chunk's arrays,
:mod:`cwproc.pipeline.stream_read`); each chunk is background-corrected, split into
stares and conical scans, screened and VAD-fitted (all per ray or per scan). The structure
function (Smalikho (2020), eqs. 1-2) is computed for the complete blocks of N scans
held so far; the scans of an incomplete last block are carried, screened, into the next
chunk, so every block is the one the whole-day run forms. Only the per-scan wind rows,
the per-block structure statistics and the (vertical) stare rays are kept; the
dissipation rate (which may pool noise over neighbouring blocks) and the stare product
are computed once over the day.

Two threads share the work (unless ``CWPROC_READ_AHEAD=0``): one plans, reads, parses
and checksums the next chunk's files, whose costly parts (the file reads, the compiled
tokenizer, ``hashlib``) release the GIL, while the caller's thread does all the
numerical work of the chunk before it, in chunk order (background correction, scan
numbering, screening and VAD fit, the structure function of the blocks). That work is
numpy operations on a chunk's arrays, each holding the GIL for its Python-level part:
a third thread that screened the next chunk beside the reduction of the one before
gained nothing over the caller's thread doing both (5 pairs of runs of a simulated
day) and cost 0.7 s more CPU, so the caller's thread is the day's critical path and
the checksums are taken in the reading thread.

The whole-day run is the definition: the choices it makes over the whole day (scan
numbering, the most common conical elevation, the azimuth step and rotation, the
background method) are recomputed at the end from the per-ray pointing kept on the way
(24 bytes a ray) and compared with those of the chunks; should any differ (a day of
mixed geometries), or a chunk fail, the unit is processed whole instead, so the
products are identical either way.
"""

from __future__ import annotations

import contextlib
import ctypes
import dataclasses
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field

import numpy as np
import xarray as xr

from cwproc import progress
from cwproc.config import Config
from cwproc.errors import CwprocError, InputFileError
from cwproc.io import FileIdentity
from cwproc.io.scans import _source_files, concat_scans, joined_attrs, scan_indices
from cwproc.pipeline.background import correct_background, find_background_files
from cwproc.pipeline.chain import (
    describe_scan_file,
    describe_scan_inputs,
    probe_attrs,
    probe_for,
    probe_mismatch,
    pulse_rate_hz,
    screened_wind,
    stare_products,
)
from cwproc.pipeline.stream_read import (
    ChunkAhead,
    ReadAhead,
    chunk_reading_possible,
    planned_chunks,
    read_ahead_enabled,
    read_planned_chunk,
)
from cwproc.pipeline.units import drop_input
from cwproc.stages import epsilon, structure, vad
from cwproc.stages.background import correction_summary
from cwproc.stages.stare import split_stares, stare_mask
from cwproc.stages.structure import INSTRUMENT_SETTINGS

#: input data joined into one chunk (bytes of the read datasets): the stages need about
#: ten times this at once (padded per-scan arrays of the robust VAD fits), so 8 MiB
#: (14 files of 180 rays x 100 gates) keeps a day under 300 MiB
STREAM_CHUNK_BYTES = 8 << 20


class StreamMismatch(Exception):
    """A chunk made a choice the whole-day run would not make: process the day whole."""


@dataclass
class StreamState:
    """What a streamed day keeps: small per-scan and per-block results, and pointing."""

    winds: list[xr.Dataset] = field(default_factory=list)
    sfs: list[xr.Dataset] = field(default_factory=list)
    stares: list[xr.Dataset] = field(default_factory=list)
    #: screened rays and wind rows of the scans of the incomplete last block
    carry: tuple[xr.Dataset, xr.Dataset] | None = None
    scan_offset: int = 0
    last_time: np.datetime64 | None = None
    #: per-ray time, azimuth, elevation and streamed scan index of every chunk
    pointing: list[tuple[np.ndarray, ...]] = field(default_factory=list)
    #: (vad elevation, vad scans left out) of every chunk with conical scans
    choices: set[tuple[object, ...]] = field(default_factory=set)
    #: the SNR correction method of every chunk ("None": not corrected)
    snr_corrections: set[str] = field(default_factory=set)
    background_files: set[str] = field(default_factory=set)
    #: (inputs of the unit, the background files beside them) when last looked for
    background_found: tuple[int, list] | None = None
    #: (wind time origin, ray time origin) of the structure function, from the first block
    origins: tuple[np.datetime64, np.datetime64] | None = None
    turbulence: bool = True
    #: per chunk, the rays whose SNR a background file corrected
    corrected: list[np.ndarray] = field(default_factory=list)
    #: scan type of the day's files (joined), for the scan numbering of the whole day
    scan_type: str = ""


def time_ordered(items: list, start: Callable[[object], np.datetime64]) -> list:
    """The inputs sorted by their first ray time (stable for equal times)."""
    return sorted(items, key=lambda item: start(item))


def chunks_of(items: list, load: Callable, max_bytes: int):
    """Yield lists of loaded datasets of consecutive inputs of about ``max_bytes``.

    ``load(item)`` returns the dataset of an input (reading it when not held) and is
    called once per input; the datasets are released by the caller after each chunk.
    """
    chunk: list[xr.Dataset] = []
    size = 0
    for item in items:
        ds = load(item)
        if ds is None:
            continue
        chunk.append(ds)
        size += int(ds.nbytes)
        if size >= max_bytes:
            yield chunk
            chunk, size = [], 0
    if chunk:
        yield chunk


def planned_chunk_datasets(
    ordered: list, take: Callable, took: Callable, chunk_bytes: int, ahead: bool = False
) -> Iterator[xr.Dataset | None]:
    """The chunks of ``.hpl`` files read a chunk at a time (:mod:`.stream_read`).

    ``took(item, identity, lines)`` is called for each file of a chunk read at once
    (its identity and the line :func:`~.chain.describe_scan_inputs` gives it); a chunk
    that cannot be read at once is read file by file with ``take(item)``, as
    :func:`chunks_of` does. None: a chunk whose every file was left out. With
    ``ahead``, the next chunk is planned and parsed in a second thread
    (:class:`ChunkAhead`) while the caller processes the one handed out; ``took`` and
    ``take`` still run in the caller's thread, in order.
    """
    plans = planned_chunks(ordered, chunk_bytes)
    if not ahead:
        for planned in plans:
            yield _planned_chunk(planned, read_planned_chunk(planned), take, took)
        return
    reader = ChunkAhead(plans)
    try:
        while (next_chunk := reader.next()) is not None:
            yield _planned_chunk(*next_chunk, take, took)
    finally:
        reader.close()


def _planned_chunk(
    planned: list[tuple], got: tuple | None, take: Callable, took: Callable
) -> xr.Dataset | None:
    if got is None:
        parts = [ds for item, _ in planned if (ds := take(item)) is not None]
        return concat_scans(parts) if parts else None
    chunk, files = got
    vertical = stare_mask(chunk)
    for (item, _), part in zip(planned, files, strict=True):  # checksummed by the read
        line = describe_scan_file(
            item.path, part.identity.attrs, vertical[part.start : part.stop], part.scan
        )
        took(item, part.identity, [line])
    return chunk


def number_scans(chunk: xr.Dataset, state: StreamState) -> xr.Dataset:
    """The chunk with its scan indices shifted to follow those of earlier chunks.

    Raises
    ------
    StreamMismatch
        The chunk's rays do not all come after those of the previous chunk.
    """
    time = chunk["time"].values
    if state.last_time is not None and time.size and time[0] <= state.last_time:
        raise StreamMismatch("files overlap in time")
    scan = chunk["scan"].values
    shifted = np.where(scan >= 0, scan + state.scan_offset, scan)
    if scan.size:
        state.scan_offset += int(scan.max()) + 1 if (scan >= 0).any() else 0
        state.last_time = time[-1]
    state.pointing.append(
        (
            time,
            chunk["azimuth"].values.astype(float),
            chunk["elevation"].values.astype(float),
            shifted,
        )
    )
    return chunk.assign_coords(scan=("ray", shifted, chunk["scan"].attrs))


def _join(parts: list[xr.Dataset], dim: str) -> xr.Dataset:
    """``xr.concat(parts, dim, combine_attrs="override")`` (:func:`concat_like_parts`
    when the parts allow it)."""
    if len(parts) == 1:
        return parts[0]
    joined = concat_like_parts(parts, dim)
    return joined if joined is not None else xr.concat(parts, dim=dim, combine_attrs="override")


def concat_like_parts(parts: list[xr.Dataset], dim: str) -> xr.Dataset | None:
    """Datasets of the same variables joined along ``dim``, one ``np.concatenate`` each.

    The result of ``xr.concat(parts, dim, combine_attrs="override")`` when every part
    has the variables of the first (in any order), with its dimensions and dtype, every
    data variable lies along ``dim`` and every other variable (a coordinate) equals the
    first's: the first's attributes and encodings, the variables along ``dim`` joined,
    the others the first's. ``xr.concat`` aligns and compares the parts variable by
    variable: 0.5 s for the 96 chunks of a day of wind rows and structure functions,
    against a few ms here. None when a part differs (the caller concatenates with
    xarray).
    """
    first = parts[0]
    if any(dim not in first.variables[name].dims for name in first.data_vars):
        return None
    names = list(first.variables)
    variables: dict[str, xr.Variable] = {}
    for name in names:
        var = first.variables[name]
        others = [part.variables.get(name) for part in parts[1:]]
        if any(o is None or o.dims != var.dims or o.dtype != var.dtype for o in others):
            return None
        if dim in var.dims:
            data = np.concatenate(
                [var.values, *(o.values for o in others)], axis=var.dims.index(dim)
            )
            variables[name] = xr.Variable(var.dims, data, var.attrs, var.encoding)
        elif all(o.equals(var) for o in others):
            variables[name] = var
        else:
            return None
    if any(len(part.variables) != len(names) for part in parts[1:]):
        return None
    return xr.Dataset(
        {name: variables[name] for name in first.data_vars},
        coords={name: variables[name] for name in first.coords},
        attrs=dict(first.attrs),
    )


def flush_blocks(
    screened: xr.Dataset, wind: xr.Dataset, state: StreamState, config: Config, final: bool
) -> None:
    """Structure function of the complete blocks of ``wind``; the rest is carried.

    Blocks are ``[turbulence] n_scans`` consecutive wind rows from the first of the day
    (Smalikho (2020), eq. 1), as :func:`cwproc.stages.structure.azimuth_structure_function`
    forms them on the whole day; the last, shorter block is flushed at the end.
    """

    n_scans = config.turbulence.n_scans
    n = int(wind.sizes["time"])
    k = n if final else n // n_scans * n_scans
    if k < n:
        rest = wind["scan"].values[k:]
        carried = np.flatnonzero(np.isin(screened["scan"].values, rest))
        state.carry = (screened.isel(ray=carried), wind.isel(time=slice(k, None)))
    else:
        state.carry = None
    if k == 0:
        return
    done = wind.isel(time=slice(0, k)) if k < n else wind
    if state.origins is None:
        in_wind = np.isin(screened["scan"].values, done["scan"].values)
        state.origins = (done["time"].values[0], screened["time"].values[in_wind].min())
    try:
        state.sfs.append(
            structure.azimuth_structure_function(
                screened,
                done,
                n_scans=n_scans,
                max_lag_deg=config.turbulence.max_lag_deg,
                min_lags=config.turbulence.min_lags,
                time_origins=state.origins,
            )
        )
    except CwprocError as exc:
        raise StreamMismatch(f"structure function of a chunk: {exc}") from None


def take_chunk(chunk: xr.Dataset, state: StreamState, config: Config) -> None:
    """Stares kept, conical scans screened, fitted and their complete blocks reduced."""
    others = split_chunk(chunk, state)
    if others is not None:
        reduce_chunk(*screen_chunk(others, config), state, config)


def split_chunk(chunk: xr.Dataset, state: StreamState) -> xr.Dataset | None:
    """The stares of a chunk kept in ``state``; its other rays returned (None: none)."""
    # a chunk without stares is taken as it is (split_stares would copy every ray)
    vertical = stare_mask(chunk)
    stares, others = split_stares(chunk) if vertical.any() or not vertical.size else (None, chunk)
    if stares is not None:
        state.stares.append(stares)
    return others


def screen_chunk(others: xr.Dataset, config: Config) -> tuple[xr.Dataset, xr.Dataset]:
    """Screened conical scans of a chunk and their wind rows (the day's state untouched).

    Raises
    ------
    StreamMismatch
        The screening or the VAD fit cannot run on the chunk alone.
    """
    try:
        return screened_wind(others, config)
    except CwprocError as exc:
        raise StreamMismatch(f"wind of a chunk: {exc}") from None


def reduce_chunk(
    screened: xr.Dataset, wind: xr.Dataset, state: StreamState, config: Config
) -> None:
    """A chunk's wind rows kept and its complete blocks reduced (in chunk order)."""
    state.winds.append(wind)
    state.choices.add((wind.attrs["vad_elevation_deg"], wind.attrs["vad_scans_other_elevation"]))
    if state.turbulence:
        if state.carry is not None:
            screened = _join([state.carry[0], screened], "ray")
            wind = _join([state.carry[1], wind], "time")
        flush_blocks(screened, wind, state, config, final=False)


def check_day_choices(state: StreamState, config: Config) -> None:
    """Compare the chunks' choices with the whole day's (recomputed from the pointing).

    Raises
    ------
    StreamMismatch
        Scan numbering, conical elevation, azimuth step or rotation, or the background
        method of a chunk differs from the whole day's.
    """
    time, az, el, streamed = (np.concatenate(p) for p in zip(*state.pointing, strict=True))
    whole, _ = scan_indices(time, az, el, scan_type=state.scan_type)
    if not np.array_equal(whole, streamed):
        raise StreamMismatch("scan numbering")
    if len(state.choices) > 1 or len(state.snr_corrections) > 1:
        raise StreamMismatch("conical elevation or background method")
    if not state.winds:
        return
    layout, phi, _, n_other = vad.select_conical_scans(
        vad.scan_layout(whole, np.isfinite(az) & np.isfinite(el)), el
    )
    wind_scans = np.concatenate([w["scan"].values for w in state.winds])
    chosen, other = next(iter(state.choices))
    if (phi, n_other) != (chosen, other) or not np.array_equal(layout.scan_ids, wind_scans):
        raise StreamMismatch("conical scans of the day")
    if state.sfs:
        rays = np.isin(whole, wind_scans)
        day_step = structure.azimuth_step(az[rays], whole[rays])
        for sf in state.sfs:
            if (float(sf["azimuth_step"].values[0]), float(sf.attrs["rotation"])) != day_step:
                raise StreamMismatch("azimuth step")


def day_attrs(first: dict, files: list[str], scan_types: list[str], state: StreamState) -> dict:
    """Attributes of the whole day's scans (those the whole-day run would carry)."""

    attrs = joined_attrs(first, files, scan_types)
    if state.snr_corrections:
        snr_correction = next(iter(state.snr_corrections))
        if snr_correction != "None":
            attrs["snr_correction"] = snr_correction
            attrs["background_files"] = sorted(state.background_files)
    return attrs


def stream_products(
    state: StreamState, attrs: dict, config: Config, notes: list[str] | None
) -> dict[str, xr.Dataset]:
    """Wind, turbulence and stare products of the day from what the chunks kept."""

    products: dict[str, xr.Dataset] = {}
    any_wind = bool(state.winds)
    # each list is released once joined: the chunks' pieces are not held by the
    # dissipation-rate fit, whose working arrays make the day's peak memory
    if state.winds:
        wind = _join(state.winds, "time")
        state.winds = []
        wind.attrs = {**attrs, **{k: v for k, v in wind.attrs.items() if k.startswith("vad_")}}
        products["wind"] = wind
    if state.sfs:
        sf = _join(state.sfs, "time")
        state.sfs = []
        sf.attrs["instrument"] = str(attrs.get("instrument", ""))
        for key in INSTRUMENT_SETTINGS:  # the day's, as the whole-day run has them
            sf.attrs.pop(key, None)
            if key in attrs:
                sf.attrs[key] = attrs[key]
        with heap_returned():
            products["turbulence"] = epsilon.estimate_epsilon(
                sf,
                probe=probe_for(config, attrs),
                lag_number=config.turbulence.lag_number,
                model=config.turbulence.model,
                prf_hz=pulse_rate_hz(config, attrs),
            )
            products["turbulence"].attrs.update(probe_attrs(config, attrs))
    elif state.turbulence and any_wind and notes is not None:
        notes.append("turbulence not computed: no complete block of scans")
    if state.stares and config.stare.enabled:
        stares = _join(state.stares, "ray")
        state.stares = []
        stares.attrs = dict(attrs)
        products["stare"] = stare_products(stares, products.get("wind"), config, notes)
    return products


#: glibc ``mallopt`` parameters: free memory at the top of the heap above which ``free``
#: returns it to the system; size from which ``malloc`` maps memory apart (left at the
#: chunks' value after them)
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3
#: while the chunks are processed: arrays up to glibc's largest threshold (64-bit) come
#: from the heap, and up to this much free heap is kept for the next chunk's arrays
_CHUNK_MMAP_BYTES, _CHUNK_TRIM_BYTES = 32 << 20, 256 << 20
#: glibc's default trim threshold, set back after the chunks
_DEFAULT_TRIM_BYTES = 128 << 10


#: free heap kept at the top while the dissipation rate is fitted (its groups of blocks
#: make and drop arrays of the same sizes)
_EPSILON_TRIM_BYTES = 64 << 20


@contextlib.contextmanager
def heap_returned() -> Iterator[None]:
    """Run a step with the chunks' freed heap returned to the system first (glibc only).

    After the chunks, tens of MiB of freed heap stay resident, and the dissipation
    rate's working arrays (A-table evaluations, the delta-method errors of groups of 40
    blocks) would be laid out in and beside them. The free heap is given back
    (``malloc_trim``), so the step's peak is what it uses; its arrays then come from the
    heap as the chunks' did (up to 32 MiB, :func:`heap_kept`) and up to
    :data:`_EPSILON_TRIM_BYTES` of it is kept free while the step runs, so that one
    group's arrays reuse the pages of the group before (afterwards glibc's default trim
    threshold is set back). For a day of 1920 scans the whole run then faults in about
    116 000 pages instead of 280 000 when every array of 128 KiB and more was mapped
    apart (until 2026-11-26; 0.3-1.0 s in interleaved runs), for a peak about 10 MiB
    higher (247-260 against 245-253 MiB). The values computed are the same; with another C library
    this does nothing.
    """
    libc = _glibc()
    if libc is None:
        yield
        return
    libc.malloc_trim(0)
    libc.mallopt(_M_TRIM_THRESHOLD, _EPSILON_TRIM_BYTES)
    try:
        yield
    finally:
        libc.mallopt(_M_TRIM_THRESHOLD, _DEFAULT_TRIM_BYTES)


@contextlib.contextmanager
def heap_kept() -> Iterator[None]:
    """Process the chunks with their freed arrays kept in the heap (glibc only).

    Each chunk's stages make and drop hundreds of arrays of a few MiB (the padded
    (scan, ray, gate) arrays of the fits, the structure function's); by default glibc
    maps such arrays apart or returns the freed heap top to the system, so every one
    is faulted in page by page and zeroed by the kernel again (about a third of the
    stages' time, and more when the cores are shared). Here arrays up to 32 MiB come
    from the heap and up to 256 MiB of free heap is kept, so the next array reuses pages
    already resident; the peak memory is that of the largest chunk's arrays in use, as
    before. Afterwards the free heap is given back (``malloc_trim``) and the default
    trim threshold restored. The values computed are the same; with another C library
    this does nothing.
    """
    libc = _glibc()
    if libc is None:
        yield
        return
    libc.mallopt(_M_MMAP_THRESHOLD, _CHUNK_MMAP_BYTES)
    libc.mallopt(_M_TRIM_THRESHOLD, _CHUNK_TRIM_BYTES)
    try:
        yield
    finally:
        libc.mallopt(_M_TRIM_THRESHOLD, _DEFAULT_TRIM_BYTES)
        libc.malloc_trim(0)


def _glibc() -> ctypes.CDLL | None:
    """The GNU C library when this process runs on it (with ``malloc_trim``), else None."""
    try:
        libc = ctypes.CDLL(None)  # the symbols of the process, its C library's among them
    except OSError:
        return None
    if not hasattr(libc, "malloc_trim") or not hasattr(libc, "mallopt"):
        return None
    return libc


def stream_scan_unit(
    unit,
    config: Config,
    notes: list[str] | None,
    load: Callable,
    chunk_bytes: int = STREAM_CHUNK_BYTES,
    read_ahead: bool | None = None,
) -> dict[str, xr.Dataset] | None:
    """Products of a scan unit processed chunk by chunk; None when it must run whole.

    Parameters
    ----------
    unit : cwproc.pipeline.ProductUnit
        A scan unit; its inputs carry ``start`` (first ray time).
    config : Config
    notes : list of str, optional
        Receives the notes of the run (only when the streamed run succeeds).
    load : callable
        ``load(item) -> xarray.Dataset`` reading an input whose data are not held.
    chunk_bytes : int
        Input data joined into one chunk (bytes).
    read_ahead : bool, optional
        Read ahead: the next files read (and checksummed) in a second thread
        (:class:`ChunkAhead` for chunks read at once, else :class:`ReadAhead`; at most
        one chunk ahead) while the caller's thread processes the chunk before it; None:
        unless ``CWPROC_READ_AHEAD=0`` (:func:`read_ahead_enabled`). The products, notes
        and failures are the same either way.

    Returns
    -------
    dict or None
        ``{product name: dataset}``, identical to :func:`cwproc.pipeline.process_scan_day`
        of the whole day; None when a chunk's choices differ from the day's (see the
        module docstring) and the caller must process the day whole.
    """

    state = StreamState(turbulence=config.turbulence.enabled)
    own: list[str] = []
    seen: dict[int, FileIdentity] = {}
    position = {id(item): k for k, item in enumerate(unit.inputs)}

    def read(item) -> xr.Dataset | None:
        return item.dataset if item.dataset is not None else load(item)

    ordered = time_ordered(list(unit.inputs), lambda item: item.start)
    by_chunk = chunk_reading_possible(unit, config)
    reading_ahead = read_ahead_enabled(read_ahead)
    ahead = ReadAhead(ordered, read, chunk_bytes) if reading_ahead and not by_chunk else None

    files_done = contextlib.ExitStack()  # a bar of the day's files (when progress is on)
    files_bar = files_done.enter_context(
        progress.bar(desc=f"{unit.key}", total=len(ordered), unit="file")
    )

    def took(item, identity: FileIdentity, lines: list[str]) -> None:
        files_bar.update(1)
        item.dataset = None  # the chunk holds it now; released with the chunk
        # for products; its attributes are the file's (source files, scan type) below
        item.identity = identity
        own.extend(lines)
        seen[position[id(item)]] = identity

    def take(item) -> xr.Dataset | None:
        try:
            ds = ahead.load(item) if ahead is not None else read(item)
        except InputFileError as exc:  # identified by its header, damaged beyond it
            drop_input(unit, item, exc)
            return None
        item.dataset = None
        if ds is not None:
            identity = FileIdentity(dict(ds.attrs), ds.variables["time"].values[:1])
            took(item, identity, describe_scan_inputs(_single(unit, item, ds)))
        return ds

    if by_chunk:
        chunks = planned_chunk_datasets(ordered, take, took, chunk_bytes, reading_ahead)
    else:
        chunks = (concat_scans(parts) for parts in chunks_of(ordered, take, chunk_bytes))
    try:
        with heap_kept():  # the chunks' arrays reuse the freed heap
            for chunk in chunks:
                if chunk is None:
                    continue  # every file of the chunk damaged beyond its header
                take_chunk(prepared_chunk(chunk, unit, config, own, state), state, config)
                del chunk  # released before the next chunk is read (and before epsilon)
        if not seen:  # every input damaged beyond its header: each has its failure line
            return {} if not unit.inputs else None
        if state.carry is not None:
            flush_blocks(*state.carry, state, config, final=True)
        firsts = [seen[k] for k in sorted(seen)]
        files = [f for ds in firsts for f in _source_files(ds)]
        types = [str(ds.attrs.get("scan_type", "")) for ds in firsts]
        state.scan_type = "; ".join(t for t in dict.fromkeys(types) if t)
        check_day_choices(state, config)
        state.pointing = []  # 24 bytes a ray of the day: not needed any more
    except StreamMismatch:
        return None
    finally:
        files_done.close()
        chunks.close()  # stops the reading thread of a chunk reader
        if ahead is not None:
            ahead.close()
    if not state.winds:
        return None  # no conical scan: the whole-day run words what it cannot make
    if state.corrected:
        own.append(background_summary(state))
    products = stream_products(state, day_attrs(firsts[0].attrs, files, types, state), config, own)
    if notes is not None:
        notes.extend(dict.fromkeys(own))
    return products


def prepared_chunk(
    chunk: xr.Dataset,
    unit,
    config: Config,
    notes: list[str],
    state: StreamState,
) -> xr.Dataset:
    """A chunk corrected and its scans numbered after the earlier chunks' (in chunk
    order), for :func:`take_chunk`."""
    chunk = corrected_chunk(chunk, unit, config, notes, state)
    state.scan_type = str(chunk.attrs.get("scan_type", ""))
    chunk = number_scans(chunk, state)
    if state.turbulence and not (state.winds or state.stares):
        mismatch = probe_mismatch(chunk, config)  # the first chunk of the day's data
        if mismatch:
            state.turbulence = False
            notes.append(f"turbulence not computed: {mismatch}")
    return chunk


def corrected_chunk(
    chunk: xr.Dataset, unit, config: Config, notes: list[str], state: StreamState
) -> xr.Dataset:
    """The chunk with its SNR background-corrected (:func:`~.background.correct_background`).

    The per-chunk summary line is left out of ``notes`` and the rays counted instead, so
    the day gets one summary (:func:`background_summary`), as the whole-day run words it.
    """

    own: list[str] = []
    if state.background_found is None or state.background_found[0] != len(unit.inputs):
        # the unit only loses inputs (damaged beyond their header): look again then only
        paths = (item.path for item in unit.inputs)
        found = find_background_files(paths, config.background.folder or None)
        state.background_found = (len(unit.inputs), found)
    out = correct_background(chunk, unit, config, own, files=state.background_found[1])
    state.snr_corrections.add(str(out.attrs.get("snr_correction")))
    state.background_files.update(out.attrs.get("background_files", []))
    if "background_time" in out and own:
        own.pop()  # the summary line correct_snr appends last
        state.corrected.append(~np.isnat(out["background_time"].values))
    notes.extend(own)
    return out


def background_summary(state: StreamState) -> str:
    """One line for the day: rays whose SNR was corrected, with how many files."""

    done = np.concatenate(state.corrected)
    used = sorted(state.background_files)
    return correction_summary(done, used, np.where(done, 0, -1))


def _single(unit, item, ds: xr.Dataset):
    """A one-input copy of ``unit`` holding ``ds`` (for per-file descriptions)."""

    return dataclasses.replace(unit, inputs=[dataclasses.replace(item, dataset=ds)])
