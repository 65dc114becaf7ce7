"""The ``.hpl`` files of a streamed day read a chunk at a time (issue 15.3).

A chunk of files that follow each other in time is parsed straight into the chunk's
arrays (:func:`cwproc.io.halo_files.read_hpl_run`) instead of one dataset per file
joined afterwards; what each file's own dataset would have said (attributes, first
time, scans) comes with it, for provenance and the per-file notes. A chunk with any
damaged, changed or held file is read file by file as before, so that a damaged file
is left out alone, named with its line, and a changed one is caught by its checksum.

The reading runs ahead of the processing in a thread of its own (:class:`ChunkAhead`,
:class:`ReadAhead`) unless ``CWPROC_READ_AHEAD=0`` (:func:`read_ahead_enabled`).
"""

from __future__ import annotations

import multiprocessing
import os
import threading
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor

import xarray as xr

from cwproc.config import Config
from cwproc.io import Format
from cwproc.io.halo_files import HplFilePart, plan_hpl_file, planned_bytes, read_hpl_run
from cwproc.pipeline.input_files import InputFile, file_signature, reader_options
from cwproc.pipeline.product_units import ProductUnit


def chunk_reading_possible(unit: ProductUnit, config: Config) -> bool:
    """Whether the files of ``unit`` may be read a chunk at a time: ``.hpl`` files
    (read with no reader options), each held or with the signature of its checksum."""
    if reader_options(config, Format.HPL):
        return False
    return all(
        item.format is Format.HPL
        and item.day is None
        and (item.dataset is not None or item.signature is not None)
        for item in unit.inputs
    )


def planned_chunks(items: list[InputFile], max_bytes: int) -> Iterator[list[tuple]]:
    """Consecutive inputs of about ``max_bytes`` of datasets, each with its plan.

    ``(item, plan)`` pairs: ``plan`` is the file's header and line count
    (:func:`cwproc.io.halo_files.plan_hpl_file`; ``None`` for a held dataset or a file
    whose header or body is off), with the file's checksum when the item has none yet
    (identified by its header alone: the plan's read takes it; the caller gives it to
    the item once the chunk is read unchanged) and its data lines, kept for the parse
    (each file read once); the header is the one the item's identity holds (parsed
    when the files were grouped; the chunk is read only when every file still has the
    signature taken then, :func:`read_planned_chunk`); sizes are those of the datasets
    the files make (:func:`cwproc.io.halo_files.planned_bytes`), as when each is read
    alone.
    """
    chunk: list[tuple] = []
    size = 0
    for item in items:
        if item.dataset is not None:
            plan, nbytes = None, int(item.dataset.nbytes)
        else:
            plan = plan_hpl_file(
                item.path, checksum=item.sha256 is None, keep_body=True, identity=item.identity
            )
            nbytes = 0 if plan is None else planned_bytes(plan)
        chunk.append((item, plan))
        size += nbytes
        if size >= max_bytes:
            yield chunk
            chunk, size = [], 0
    if chunk:
        yield chunk


def _unchanged(items: list[InputFile]) -> bool:
    """Whether every file still has the signature taken with its checksum."""
    try:
        return all(file_signature(item.path) == item.signature for item in items)
    except OSError:
        return False


def read_planned_chunk(chunk: list[tuple]) -> tuple[xr.Dataset, list[HplFilePart]] | None:
    """The files of a planned chunk as one dataset and their parts, or ``None`` (read
    them one by one): a held dataset or damaged file among them, a file changed since
    its checksum (before or after the read), or rays not running forward in time.

    The items without a checksum get the SHA-256 of the bytes their plan read
    (:attr:`cwproc.io.halo_files._FilePlan.sha256`), unchanged since: hashed here, in
    the reading thread when reading ahead, beside the caller's numerical work (the
    day's critical path; ``hashlib`` releases the GIL).
    """
    items = [item for item, _ in chunk]
    plans = [plan for _, plan in chunk]
    if any(plan is None for plan in plans) or not _unchanged(items):
        return None
    got = read_hpl_run(plans)
    if got is None or not _unchanged(items):
        return None
    for item, plan in chunk:
        if item.sha256 is None:
            item.sha256 = plan.sha256
    return got


#: environment variable that turns the reading thread of a streamed day off ("0", also
#: ``false``, ``no``, ``off``) or on (anything else) whatever the default
READ_AHEAD_VARIABLE = "CWPROC_READ_AHEAD"


def read_ahead_enabled(read_ahead: bool | None = None) -> bool:
    """Whether a streamed day reads ahead in a second thread: ``read_ahead`` when given, else
    the environment variable ``CWPROC_READ_AHEAD`` when set (``0``, ``false``, ``no``,
    ``off``: not; anything else: yes), else unless this process is a child of a
    process pool (``cwproc batch --workers N``, a Dask worker), whose processes already
    take the cores.

    With it, the next chunk is read, parsed and checksummed in a second thread
    (:class:`ChunkAhead`; chunks not read at once, file by file: :class:`ReadAhead`)
    while the caller's thread processes the chunk before it
    (:func:`cwproc.pipeline.stream.stream_scan_unit`); the products, notes and failures
    are those of the serial run. On the shared 2-core machine a day of 1920 scans took
    0.74-0.84 of the serial time with part of the second core free, and up to 1.16
    times it when other jobs held both cores (``docs/DEVELOPING.md``, Performance).
    """
    if read_ahead is not None:
        return bool(read_ahead)
    value = os.environ.get(READ_AHEAD_VARIABLE)
    if value is None:
        return multiprocessing.parent_process() is None
    return value.strip().lower() not in ("0", "false", "no", "off")


class ReadAhead:
    """The inputs of a day read in a second thread, in order, while chunks are processed.

    ``read(item)`` runs in the thread for each item in turn, at most ``max_bytes`` of
    datasets ahead of what :meth:`load` has handed out (and always the next one);
    :meth:`load` hands out the results in the same order and raises an item's error
    (e.g. :class:`~cwproc.errors.InputFileError` naming the file and line) where the
    serial read would have raised it, so that everything else (dropped inputs, notes)
    happens in the caller's thread, in the serial order. The parser (the compiled
    tokenizer) and file reads release the GIL, so reading the next files overlaps the
    numerical work of the current chunk. :meth:`close` stops the thread (after the file
    it is reading) and waits for it.
    """

    def __init__(self, items: list, read: Callable, max_bytes: int) -> None:
        self._items = list(items)
        self._read = read
        self._max = max(int(max_bytes), 1)
        self._done: dict[int, tuple[object, BaseException | None, int]] = {}
        self._cond = threading.Condition()
        self._ahead = 0  # bytes read, not handed out
        self._next = 0  # index of the next item to hand out
        self._stop = False
        self._finished = False
        self._thread = threading.Thread(target=self._run, name="cwproc-read-ahead", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        try:
            for k, item in enumerate(self._items):
                with self._cond:
                    while not self._stop and k > self._next and self._ahead >= self._max:
                        self._cond.wait()
                    if self._stop:
                        return
                try:
                    value, error = self._read(item), None
                except BaseException as exc:  # handed to the caller with its item
                    value, error = None, exc
                size = int(value.nbytes) if isinstance(value, xr.Dataset) else 0
                with self._cond:
                    self._done[k] = (value, error, size)
                    self._ahead += size
                    self._cond.notify_all()
        finally:
            with self._cond:
                self._finished = True
                self._cond.notify_all()

    def load(self, item) -> xr.Dataset | None:
        """The dataset of ``item`` (the next input in order), or its error raised."""
        with self._cond:
            k = self._next
            if k >= len(self._items) or self._items[k] is not item:
                raise ValueError("ReadAhead.load: inputs must be taken in their order")
            while k not in self._done:
                if self._finished:
                    raise RuntimeError("the reading thread stopped before the input was read")
                self._cond.wait()
            value, error, size = self._done.pop(k)
            self._ahead -= size
            self._next += 1
            self._cond.notify_all()
        if error is not None:
            raise error
        return value  # type: ignore[return-value]

    def close(self) -> None:
        """Stop reading ahead and wait for the thread (it ends after its current file)."""
        with self._cond:
            self._stop = True
            self._cond.notify_all()
        self._thread.join()
        self._done.clear()


class ChunkAhead:
    """The planned chunks of a day parsed one chunk ahead in a second thread.

    :meth:`next` returns ``(planned, read)`` of the next chunk (``read`` as
    :func:`~.stream_read.read_planned_chunk` gives it), waiting for the thread if it is
    not ready, and starts the planning and parsing of the chunk after it; an error of
    the thread is raised there. So while a chunk is processed, at most one more is
    held. The compiled tokenizer and the file reads release the GIL, so the parsing
    runs on the second core beside the numerical work of the stages.
    """

    def __init__(self, plans: Iterator[list[tuple]]) -> None:
        self._plans = plans
        self._pool = ThreadPoolExecutor(1, thread_name_prefix="cwproc-chunk-ahead")
        self._pending = self._pool.submit(self._read_next)

    def _read_next(self) -> tuple[list[tuple], tuple | None] | None:
        planned = next(self._plans, None)
        return None if planned is None else (planned, read_planned_chunk(planned))

    def next(self) -> tuple[list[tuple], tuple | None] | None:
        """The next planned chunk and its reading; None after the last."""
        got = self._pending.result()
        if got is not None:
            self._pending = self._pool.submit(self._read_next)
        return got

    def close(self) -> None:
        """Wait for the chunk being read (it is dropped) and stop the thread."""
        self._pool.shutdown(wait=True, cancel_futures=True)
