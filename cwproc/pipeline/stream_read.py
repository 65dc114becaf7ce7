"""The ``.hpl`` files of a streamed day read a chunk at a time (issue 15.3).

A chunk of files that follow each other in time is parsed straight into the chunk's
arrays (:func:`cwproc.io.halo_files.read_hpl_run`) instead of one dataset per file
joined afterwards; what each file's own dataset would have said (attributes, first
time, scans) comes with it, for provenance and the per-file notes. A chunk with any
damaged, changed or held file is read file by file as before, so that a damaged file
is left out alone, named with its line, and a changed one is caught by its checksum.
"""

from __future__ import annotations

from collections.abc import Iterator

import xarray as xr

from cwproc.config import Config
from cwproc.io import Format
from cwproc.io.halo_files import HplFilePart, plan_hpl_file, planned_bytes, read_hpl_run
from cwproc.pipeline.units import InputFile, ProductUnit, file_signature, reader_options


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
    whose header or body is off); sizes are those of the datasets the files make
    (:func:`cwproc.io.halo_files.planned_bytes`), as when each is read alone.
    """
    chunk: list[tuple] = []
    size = 0
    for item in items:
        if item.dataset is not None:
            plan, nbytes = None, int(item.dataset.nbytes)
        else:
            plan = plan_hpl_file(item.path)
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
    its checksum (before or after the read), or rays not running forward in time."""
    items = [item for item, _ in chunk]
    plans = [plan for _, plan in chunk]
    if any(plan is None for plan in plans) or not _unchanged(items):
        return None
    got = read_hpl_run(plans)
    if got is None or not _unchanged(items):
        return None
    return got
