"""The executor of the scan chain: one chunk (the whole day) or many (bounded memory).

:func:`run_scan_chain` runs :class:`~cwproc.pipeline.scan_chain.ScanChain` over the chunks
of a day, in time order. Each chunk is background-corrected, split into stares and
conical scans, screened and VAD-fitted (all per ray or per scan); the structure function
(Smalikho (2020), eqs. 1-2) is computed for the complete blocks of N scans held so far
and the scans of an incomplete last block are carried, screened, into the next chunk, so
every block is the one the whole-day run forms. Only the per-scan wind rows, the
per-block structure statistics and the (vertical) stare rays are kept; the dissipation
rate (which may pool noise over neighbouring blocks) and the stare product are computed
once over the day (:meth:`~cwproc.pipeline.scan_chain.ScanChain.finish`). The whole day is the
same function over one chunk (``whole=True``, :func:`~cwproc.pipeline.process_scan_day`),
so one code path makes the products either way.

The whole-day run is the definition: what it decides over the whole day (scan numbering,
the most common conical elevation, the azimuth step and rotation, the background
method) is decided again at the end from the per-ray pointing kept on the way (24 bytes
a ray, :meth:`~cwproc.pipeline.scan_chain.ScanChain.decisions`) and compared with what the
chunks decided; should any differ (a day of mixed geometries), or a chunk fail,
:func:`run_scan_chain` returns None and the caller runs the day whole, so the products
are identical either way.

A unit's files are read into chunks of about ``STREAM_CHUNK_BYTES`` by
:class:`UnitChunks` (``.hpl`` files parsed straight into the chunk's arrays,
:mod:`cwproc.pipeline.stream_read`). Two threads share the work (unless
``CWPROC_READ_AHEAD=0``): one plans, reads, parses and checksums the next chunk's files,
whose costly parts (the file reads, the compiled tokenizer, ``hashlib``) release the
GIL, while the caller's thread does all the numerical work of the chunk before it, in
chunk order. A third thread that screened the next chunk beside the reduction of the one
before gained nothing (5 pairs of runs of a simulated day) and cost 0.7 s more CPU, so
the caller's thread is the day's critical path and the checksums are taken in the
reading thread.
"""

from __future__ import annotations

import contextlib
import dataclasses
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import xarray as xr

from cwproc import memory, progress
from cwproc.config import Config
from cwproc.errors import CwprocError, InputFileError
from cwproc.io import FileIdentity
from cwproc.io.scan_join import concat_scans, joined_attrs, source_files
from cwproc.pipeline.background_files import SnrCorrection, find_background_files
from cwproc.pipeline.product_units import ProductUnit, drop_input
from cwproc.pipeline.scan_chain import (
    Carry,
    DayDecisions,
    DayParts,
    PartsDiffer,
    Pointing,
    ScanChain,
    describe_scan_file,
    describe_scan_inputs,
    vertical_rays,
)
from cwproc.pipeline.stream_read import (
    ChunkAhead,
    ReadAhead,
    chunk_reading_possible,
    planned_chunks,
    read_ahead_enabled,
    read_planned_chunk,
)

__all__ = [
    "STREAM_CHUNK_BYTES",
    "ChunkAhead",
    "ReadAhead",
    "UnitChunks",
    "read_ahead_enabled",
    "run_scan_chain",
    "stream_unit",
]

#: input data joined into one chunk (bytes of the read datasets): the stages need about
#: ten times this at once (padded per-scan arrays of the robust VAD fits), so 8 MiB
#: (14 files of 180 rays x 100 gates) keeps a day under 300 MiB
STREAM_CHUNK_BYTES = 8 << 20


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
    (its identity and the line :func:`~.scan_chain.describe_scan_inputs` gives it); a chunk
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
    vertical = vertical_rays(chunk)
    for (item, _), part in zip(planned, files, strict=True):  # checksummed by the read
        line = describe_scan_file(
            item.path, part.identity.attrs, vertical[part.start : part.stop], part.scan
        )
        took(item, part.identity, [line])
    return chunk


class ChunkMismatch(Exception):
    """A chunk decided what the whole-day run would not: the day runs whole."""


@dataclass
class ChunkedDay:
    """What the executor keeps of a day: its pieces and what its chunks decided."""

    parts: DayParts
    #: screened rays and wind rows of the scans of the incomplete last block
    carry: Carry | None = None
    scan_offset: int = 0
    last_time: np.datetime64 | None = None
    #: per chunk: per-ray time, azimuth, elevation and scan index (numbered over the day)
    pointing: list[tuple[np.ndarray, ...]] = field(default_factory=list)
    #: per chunk with wind: (VAD elevation, VAD scans of other elevations)
    vad: set[tuple[float, int]] = field(default_factory=set)
    #: per structure function: (azimuth step, rotation)
    steps: set[tuple[float, float]] = field(default_factory=set)
    snr: list[SnrCorrection] = field(default_factory=list)
    #: (inputs of the unit, the background files beside them) when last looked for
    background: tuple[int, list[Path]] | None = None
    probe_checked: bool = False

    def numbered(self, chunk: xr.Dataset) -> xr.Dataset:
        """The chunk with its scan indices shifted to follow those of earlier chunks.

        Raises
        ------
        ChunkMismatch
            The chunk's rays do not all come after those of the previous chunk.
        """
        time = chunk["time"].values
        if self.last_time is not None and time.size and time[0] <= self.last_time:
            raise ChunkMismatch("files overlap in time")
        scan = chunk["scan"].values
        shifted = np.where(scan >= 0, scan + self.scan_offset, scan)
        if scan.size:
            self.scan_offset += int(scan.max()) + 1 if (scan >= 0).any() else 0
            self.last_time = time[-1]
        az, el = chunk["azimuth"].values.astype(float), chunk["elevation"].values.astype(float)
        self.pointing.append((time, az, el, shifted))
        return chunk.assign_coords(scan=("ray", shifted, chunk["scan"].attrs))

    def decided(self) -> DayDecisions:
        """What the chunks decided, as one record (:class:`ChunkMismatch`: not one thing)."""
        if len(self.vad) > 1 or len(self.steps) > 1:
            raise ChunkMismatch("conical elevation or azimuth step")
        if len({s.method for s in self.snr}) > 1:
            raise ChunkMismatch("background method")
        phi, n_other = next(iter(self.vad)) if self.vad else (None, 0)
        winds = self.parts.winds
        return DayDecisions(
            scan=np.concatenate([p[3] for p in self.pointing]),
            vad_elevation_deg=phi,
            vad_scans_other_elevation=n_other,
            wind_scans=np.concatenate(winds.arrays["scan"]) if winds else np.zeros(0, np.int64),
            azimuth_step=next(iter(self.steps)) if self.steps else None,
        )

    def day_pointing(self, scan_type: str) -> Pointing:
        time, az, el, _ = (np.concatenate(p) for p in zip(*self.pointing, strict=True))
        return Pointing(time, az, el, scan_type)


def run_scan_chain(
    chain: ScanChain,
    chunks: Iterable[xr.Dataset | None],
    *,
    whole: bool,
    notes: list[str] | None = None,
    kept: dict[str, xr.Dataset] | None = None,
    cross: xr.Dataset | None = None,
    unit: ProductUnit | None = None,
    day_attrs: Callable[[], dict] | None = None,
    stares: bool = True,
) -> dict[str, xr.Dataset] | None:
    """The products of a day of scans: ``chain`` run over its chunks, in time order.

    Parameters
    ----------
    chain : ScanChain
        The stage chain and the day's decisions.
    chunks : iterable of xarray.Dataset or None
        The day's scans in time order; ``whole``: one dataset, the day (scans numbered
        over it). None items (a chunk whose every file was left out) are skipped.
    whole : bool
        The chunk is the whole day: what cannot be made is said in ``notes`` (a wind
        that cannot be fitted raises, unless stares give a product), as the definition
        of the products. Else the day is streamed: a chunk failing or deciding
        otherwise than the whole day gives None.
    notes : list of str, optional
        Receives the notes of the run, in order.
    kept : dict, optional
        Receives the screened scans (``kept["screened"]``; ``whole`` only).
    cross : xarray.Dataset, optional
        Cross-polarised stare rays of the day for the L1 product (``whole`` only).
    unit : ProductUnit, optional
        The unit of the chunks: their SNR is corrected with its background files
        (:meth:`ScanChain.prepare`); None: the chunks are already corrected.
    day_attrs : callable, optional
        Attributes of the whole day's scans, asked once the chunks are done (streamed).
    stares : bool
        Split vertical stares off for the stare product (False: every ray is fitted).

    Returns
    -------
    dict or None
        ``{product name: dataset}``; None (streamed only) when the day must run whole.

    Raises
    ------
    CwprocError
        ``whole``: no wind can be fitted and no stare gives a product.
    ValueError
        ``whole`` with more than one dataset.
    """
    day = ChunkedDay(DayParts(attrs={}, turbulence=chain.config.turbulence.enabled))
    own: list[str] = [] if notes is None else notes
    try:
        with contextlib.nullcontext() if whole else memory.phase("chunks"):
            for k, chunk in enumerate(chunks):
                if whole and k:
                    raise ValueError("run_scan_chain(whole=True) takes one dataset, the day")
                if chunk is not None:
                    _take(chain, day, chunk, own, whole=whole, kept=kept, unit=unit, stares=stares)
                del chunk  # released before the next chunk is read (and before epsilon)
        if not whole and not _streamed_day(chain, day, day_attrs, own):
            return None
    except (ChunkMismatch, PartsDiffer):  # PartsDiffer: chunks only (one part when whole)
        return None
    return chain.finish(day.parts, notes, cross)


def _take(
    chain: ScanChain,
    day: ChunkedDay,
    chunk: xr.Dataset,
    notes: list[str],
    *,
    whole: bool,
    kept: dict[str, xr.Dataset] | None,
    unit: ProductUnit | None,
    stares: bool,
) -> None:
    """One chunk through the chain: corrected, split, fitted, its complete blocks reduced."""
    if unit is not None:
        if day.background is None or day.background[0] != len(unit.inputs):
            # the unit only loses inputs (damaged beyond their header): look again then only
            paths = (item.path for item in unit.inputs)
            found = find_background_files(paths, chain.config.background.folder or None)
            day.background = (len(unit.inputs), found)
        chunk, snr = chain.prepare(chunk, unit, day.background[1], notes)
        day.snr.append(snr)
        if whole and snr.summary:
            notes.append(snr.summary)
    if not whole:
        chunk = day.numbered(chunk)
    vertical, others = chain.split(chunk) if stares else (None, chunk)
    if vertical is not None:
        day.parts.stares.append(vertical)
    if not day.parts.attrs:
        day.parts.attrs = dict((others if others is not None else chunk).attrs)
    if others is None:
        return
    try:
        fitted = chain.fit(others)
    except CwprocError as exc:
        if not whole:
            raise ChunkMismatch(f"wind of a chunk: {exc}") from None
        if vertical is None:
            raise
        notes.append(f"wind not computed: {exc}")
        return
    if kept is not None:
        kept["screened"] = fitted.screened
    wind = fitted.wind
    day.parts.winds.append(wind)
    if not whole:  # what the chunk decided, checked against the day at the end
        day.vad.add((wind.attrs["vad_elevation_deg"], wind.attrs["vad_scans_other_elevation"]))
    if not day.parts.turbulence or int(wind.sizes.get("time", 0)) < 1:
        return
    if not day.probe_checked:  # the day's first wind rows: can its probe give eps?
        day.probe_checked = True
        note = chain.turbulence_note(others)
        if note:
            day.parts.turbulence = False
            notes.append(note)
            return
    try:
        sf, day.carry = chain.blocks(day.carry, fitted, final=whole)
    except CwprocError as exc:
        if not whole:
            raise ChunkMismatch(f"structure function of a chunk: {exc}") from None
        day.parts.turbulence = False
        notes.append(f"turbulence not computed: {exc}")
        return
    _keep_blocks(day, sf, decided=not whole)


def _keep_blocks(day: ChunkedDay, sf: xr.Dataset | None, *, decided: bool) -> None:
    """Keep the blocks of ``sf`` (and, ``decided``, their azimuth step and rotation)."""
    if sf is not None and int(sf.sizes.get("time", 0)) >= 1:
        day.parts.sfs.append(sf)
        if decided:
            day.steps.add((float(sf["azimuth_step"].values[0]), float(sf.attrs["rotation"])))


def _streamed_day(
    chain: ScanChain, day: ChunkedDay, day_attrs: Callable[[], dict] | None, notes: list[str]
) -> bool:
    """The streamed day's last block reduced, its decisions checked against the whole
    day's and its attributes set; False when there is no wind (the whole-day run words
    what it cannot make).

    Raises
    ------
    ChunkMismatch
        The chunks decided otherwise than the whole day would.
    """
    if not day.pointing:
        return False
    try:
        if day.carry is not None:
            _keep_blocks(day, chain.blocks(day.carry, None, final=True)[0], decided=True)
            day.carry = None
        attrs = dict(day_attrs()) if day_attrs is not None else dict(day.parts.attrs)
        pointing = day.day_pointing(str(attrs.get("scan_type", "")))
        decided = chain.decisions(pointing, wind=bool(day.parts.winds), step=bool(day.parts.sfs))
    except CwprocError as exc:
        raise ChunkMismatch(str(exc)) from None
    different = decided.differences(day.decided())
    day.pointing = []  # 24 bytes a ray of the day: not needed any more
    if different:
        raise ChunkMismatch(different)
    if not day.parts.winds:
        return False
    snr = SnrCorrection.of_day(day.snr)
    if snr is not None and snr.method != "None":
        attrs["snr_correction"] = snr.method
        attrs["background_files"] = list(snr.files)
    if snr is not None and snr.summary:
        notes.append(snr.summary)
    day.parts.attrs, day.parts.joined = attrs, True
    return True


# --------------------------------------------------------------------------------------
# the chunks of a unit's files
# --------------------------------------------------------------------------------------


def stream_unit(
    unit: ProductUnit,
    config: Config,
    notes: list[str] | None,
    load: Callable,
    chunk_bytes: int = STREAM_CHUNK_BYTES,
    read_ahead: bool | None = None,
) -> dict[str, xr.Dataset] | None:
    """Products of a scan unit run chunk by chunk; None when it must run whole.

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
        Read ahead (:class:`UnitChunks`); None: unless ``CWPROC_READ_AHEAD=0``. The
        products, notes and failures are the same either way.

    Returns
    -------
    dict or None
        ``{product name: dataset}``, identical to :func:`run_scan_chain` of the whole day
        (``whole=True``); None when a chunk decided otherwise (see the module docstring).
    """
    own: list[str] = []
    with UnitChunks(unit, config, load, own, chunk_bytes, read_ahead) as chunks:
        products = run_scan_chain(
            ScanChain(config), chunks, whole=False, notes=own, unit=unit, day_attrs=chunks.attrs
        )
    if products is None:
        return {} if not chunks.seen and not unit.inputs else None
    if notes is not None:
        notes.extend(dict.fromkeys(own))
    return products


class UnitChunks:
    """The scan files of a unit as chunks of about ``chunk_bytes``, in time order.

    Each file's description line (:func:`~.scan_chain.describe_scan_inputs`) is appended to
    ``notes`` as it is read; a file damaged beyond its header is left out of the unit
    with its failure line (:func:`~cwproc.pipeline.product_units.drop_input`). With
    ``read_ahead`` (None: unless ``CWPROC_READ_AHEAD=0``) the next files are read (and
    checksummed) in a second thread (:class:`ChunkAhead` for chunks read at once, else
    :class:`ReadAhead`; at most one chunk ahead) while the caller processes the chunk
    before it. A context manager: leaving it stops the reading thread.
    """

    def __init__(
        self,
        unit: ProductUnit,
        config: Config,
        load: Callable,
        notes: list[str],
        chunk_bytes: int = STREAM_CHUNK_BYTES,
        read_ahead: bool | None = None,
    ) -> None:
        self.unit, self.load, self.notes = unit, load, notes
        #: identity of each file read, by its position in the unit
        self.seen: dict[int, FileIdentity] = {}
        self._position = {id(item): k for k, item in enumerate(unit.inputs)}
        ordered = time_ordered(list(unit.inputs), lambda item: item.start)
        by_chunk = chunk_reading_possible(unit, config)
        ahead = read_ahead_enabled(read_ahead)
        self._ahead = (
            ReadAhead(ordered, self._read, chunk_bytes) if ahead and not by_chunk else None
        )
        self._done = contextlib.ExitStack()  # a bar of the day's files (when progress is on)
        self._bar = self._done.enter_context(
            progress.bar(desc=f"{unit.key}", total=len(ordered), unit="file")
        )
        if by_chunk:
            self._chunks = planned_chunk_datasets(
                ordered, self._take, self._took, chunk_bytes, ahead
            )
        else:
            parts = chunks_of(ordered, self._take, chunk_bytes)
            self._chunks = (concat_scans(p) for p in parts)

    def __iter__(self) -> Iterator[xr.Dataset | None]:
        return self._chunks

    def __enter__(self) -> UnitChunks:
        return self

    def __exit__(self, *exc: object) -> None:
        self._done.close()
        self._chunks.close()  # stops the reading thread of a chunk reader
        if self._ahead is not None:
            self._ahead.close()

    def attrs(self) -> dict:
        """Attributes of the whole day's scans (those the whole-day run carries)."""
        firsts = [self.seen[k] for k in sorted(self.seen)]
        files = [f for ds in firsts for f in source_files(ds)]
        types = [str(ds.attrs.get("scan_type", "")) for ds in firsts]
        return joined_attrs(firsts[0].attrs, files, types)

    def _read(self, item) -> xr.Dataset | None:
        return item.dataset if item.dataset is not None else self.load(item)

    def _took(self, item, identity: FileIdentity, lines: list[str]) -> None:
        self._bar.update(1)
        item.dataset = None  # the chunk holds it now; released with the chunk
        # for products; its attributes are the file's (source files, scan type) below
        item.identity = identity
        self.notes.extend(lines)
        self.seen[self._position[id(item)]] = identity

    def _take(self, item) -> xr.Dataset | None:
        try:
            ds = self._ahead.load(item) if self._ahead is not None else self._read(item)
        except InputFileError as exc:  # identified by its header, damaged beyond it
            drop_input(self.unit, item, exc)
            return None
        item.dataset = None
        if ds is not None:
            identity = FileIdentity(dict(ds.attrs), ds.variables["time"].values[:1])
            single = dataclasses.replace(self.unit, inputs=[dataclasses.replace(item, dataset=ds)])
            self._took(item, identity, describe_scan_inputs(single))
        return ds
