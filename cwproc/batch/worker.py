"""Worker-side functions (the defaults of :func:`cwproc.batch.run_batch`; run in the
driver or on Dask workers): classify one file, process one unit.
"""

from __future__ import annotations

import contextlib
import json
import os
import socket
import sys
import time
import traceback
from collections.abc import Callable, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from cwproc import memory
from cwproc.batch.records import (
    PRODUCT_FORMAT,
    FileInfo,
    UnitOutcome,
    UnitTask,
    parsed_config,
)
from cwproc.config import Config
from cwproc.errors import CwprocError, InputFileError, ProductError
from cwproc.io import Format, is_cwproc_product, sniff_format
from cwproc.pipeline import (
    InputFile,
    ProductUnit,
    format_mismatch,
    group_units,
    instrument_mismatch,
    read_input,
    run_unit,
    sonic_identity,
    sonic_span,
    unit_key,
    write_unit_products,
)

_HEAD_BYTES = 4096


def _first_time_iso(item: InputFile) -> str:
    """The earliest valid time of an input (ISO 8601 UTC, whole seconds; '' when none).

    From its data when read, else from its header (``.hpl``: the first ray's time, the
    earliest of the file since ray times run forward).
    """
    if item.identity is not None:
        t = np.asarray(item.identity.time)
    elif item.dataset is not None and "time" in item.dataset.variables:
        t = np.asarray(item.dataset["time"].values)
    else:
        return ""
    if not np.issubdtype(t.dtype, np.datetime64):
        return ""
    t = t[~np.isnat(t)]
    if t.size == 0:
        return ""
    return np.datetime_as_string(np.min(t).astype("datetime64[s]"), unit="s") + "Z"


def file_size_mtime(path: str) -> tuple[int, int]:
    """Size (bytes) and modification time (ns) of a file, as the ledger records them."""
    st = os.stat(path)
    return st.st_size, st.st_mtime_ns


def classify_file_whole(path: str, config_toml: str, config_source: str = "<batch>") -> FileInfo:
    """:func:`classify_file` reading the file whole in any format (for a file that failed
    before: a damaged ``.hpl`` body then fails at classification, as the first time)."""
    return classify_file(path, config_toml, config_source, whole=True)


def classify_file(
    path: str,
    config_toml: str,
    config_source: str = "<batch>",
    *,
    whole: bool = False,
    checksum: bool = True,
) -> FileInfo:
    """Recognise and checksum one file; find the product unit it belongs to.

    A format with a header-only identifier (``.hpl``, see ``cwproc.io.IDENTIFIERS``) is
    not parsed here: its bytes are read once, for the checksum, and its header gives the
    unit and first time; its data are read once, when its unit is processed (an input
    damaged beyond its header is then left out of the unit and recorded as a file
    failure, see :func:`process_unit_task`). Formats without such an identifier (sonic
    files, wind records, scan NetCDF) and files with reader options are read whole:
    their unit and first time come from their data. Never raises for anything the file
    can cause: problems come back in the record
    (an unexpected exception of a reader too, so that one file cannot stop a run).

    Parameters
    ----------
    path : str
        The input file.
    config_toml : str
        The configuration as TOML text (:meth:`cwproc.config.Config.to_toml`).
    config_source : str
        Where the configuration came from (recorded in products).
    whole : bool
        Read the file whole whatever its format.
    checksum : bool
        Take the checksum of a file identified by its header (one more read of its
        bytes). ``False``: its ``sha256`` stays "" and the unit that reads its data
        takes it from the bytes it parses (:func:`process_unit_task`): a new file is
        read once in a run (:func:`classify_batch`).
    """
    config, chash = parsed_config(config_toml, config_source)
    try:
        size, mtime_ns = file_size_mtime(path)
        with open(path, "rb") as fh:
            head = fh.read(_HEAD_BYTES)
    except OSError as exc:
        return FileInfo(path, 0, 0, "error", error=f"{path}: cannot read: {exc.strerror or exc}")
    base = FileInfo(path, size, mtime_ns, "unrecognised", config_hash=chash)
    fmt = sniff_format(head)
    skipped = _skipped_by_its_head(path, head, fmt, base, config)
    if skipped is not None:
        return skipped
    assert fmt is not None
    try:
        with local_dask_scheduler():
            item = read_input(path, config, identify_only=not whole, checksum=checksum)
        kind, key = unit_key(item)
    except CwprocError as exc:
        return replace(base, status="error", format=fmt.value, error=str(exc))
    except Exception as exc:  # a bug in a reader: this file fails, the run goes on
        return replace(
            base,
            status="error",
            format=fmt.value,
            error=f"{path}: internal error of the {fmt.value} reader {type(exc).__name__}: {exc}",
        )
    wrong = instrument_mismatch(item, config)
    if wrong:  # the failure cwproc retrieve reports for it
        return replace(base, status="error", format=fmt.value, error=wrong)
    identity = sonic_identity(item)
    return replace(
        base,
        status="ok",
        sha256=item.sha256 or "",
        format=item.format.value,
        kind=kind,
        unit=key,
        start=_first_time_iso(item),
        identity=json.dumps({"fields": identity, "span": sonic_span(item)}) if identity else "",
    )


def _skipped_by_its_head(
    path: str, head: bytes, fmt: Format | None, base: FileInfo, config: Config
) -> FileInfo | None:
    """The record of a file its first bytes already rule out (empty, not a format cwproc
    reads, a cwproc product, a background file, a format the configuration does not
    read); None for a file to read."""
    if not head:
        return replace(base, error=f"{path}: file is empty")
    if fmt is None:
        return replace(base, error=f"{path}:1: not a format cwproc reads")
    if fmt is Format.SCAN_NETCDF and is_cwproc_product(path):
        return replace(
            base,
            format=PRODUCT_FORMAT,
            error=f"{path}: a cwproc product, not an instrument file: skipped",
        )
    if fmt is Format.HALO_BACKGROUND:
        return replace(
            base,
            format=fmt.value,
            error=f"{path}: a Stream Line background file (used for the SNR of the scans "
            "beside it, not a product input): skipped",
        )
    mismatch = format_mismatch(path, fmt, config)
    if mismatch:
        return replace(base, status="other_format", format=fmt.value, error=mismatch)
    return None


#: how :func:`classify_batch` classifies a file: by its header, its checksum left to its
#: unit (a file new to the ledger); by its header with its checksum (a file the ledger
#: knew with another size or time: an unchanged content leaves its unit up to date);
#: read whole (a file that failed before: a damaged body fails here again)
CLASSIFY_MODES = ("header", "checksum", "whole")


def classify_batch(
    items: Sequence[tuple[str, str]],
    classify: Callable[..., FileInfo],
    config_toml: str,
    config_source: str = "<batch>",
) -> list[FileInfo]:
    """Classify many files in one task: ``(path, mode)`` pairs (:data:`CLASSIFY_MODES`).

    One task per file made a lidar-year (700,000 files) 700,000 scheduler round trips
    (about 10 ms each on Dask); one per batch of thousands of files plans it in a few
    hundred (:func:`cwproc.batch.run.classification_batches`). ``classify`` is
    :func:`classify_file` (the modes apply) or a function ``(path, config_toml,
    config_source) -> FileInfo`` of the caller's (called as is). Never raises: a file
    whose classification raised gets a failure record naming it.
    """
    infos = []
    for path, mode in items:
        try:
            if classify is classify_file:
                info = classify_file(
                    path,
                    config_toml,
                    config_source,
                    whole=mode == "whole",
                    checksum=mode != "header",
                )
            else:
                info = classify(path, config_toml, config_source)
        except Exception as exc:  # a bug in a classifier: this file fails, the batch goes on
            info = unclassified(path, exc)
        infos.append(info)
    return infos


def unclassified(path: str, exc: object) -> FileInfo:
    """The failure record of a file whose classification could not run (``exc``)."""
    size, mtime_ns = 0, 0
    with contextlib.suppress(OSError):
        size, mtime_ns = file_size_mtime(path)
    return FileInfo(
        path, size, mtime_ns, "error", error=f"{path}: could not be classified: {exc!r}"
    )


def peak_rss_mib() -> float:
    """Peak resident memory of this process so far (MiB).

    Linux ``VmHWM`` of ``/proc/self/status``, which starts afresh at ``exec`` (unlike
    ``ru_maxrss``, which a spawned worker inherits from the process that started it);
    ``ru_maxrss`` where ``/proc`` is missing.
    """
    try:
        with open("/proc/self/status", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) / 1024.0  # kB
    except (OSError, ValueError, IndexError):
        pass
    import resource

    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return rss / 1024.0 if sys.platform != "darwin" else rss / 2**20


def local_dask_scheduler() -> contextlib.AbstractContextManager[Any]:
    """Within a unit, run any dask work synchronously in this process.

    On a Dask worker, xarray otherwise sees the distributed scheduler and guards each
    NetCDF variable write with a cluster-wide lock (a round trip to the scheduler per
    variable: 5-8 times slower products); a unit is one task on one thread anyway.
    """
    try:
        import dask
    except ImportError:
        return contextlib.nullcontext()
    return dask.config.set(scheduler="synchronous")


def process_unit_task(task: UnitTask) -> UnitOutcome:
    """Read, process and write the products of one unit (worker side).

    The inputs are read again and their checksums compared with the ones the unit was
    planned with: a file that changed in between fails the unit (the next run picks up
    the new content). Never raises for anything the data can cause; an unexpected
    exception (a bug) comes back with its traceback in ``detail``.
    """
    t0 = time.perf_counter()
    host = socket.gethostname()

    def outcome(
        products: Sequence[Path] = (),
        error: str = "",
        detail: str = "",
        notes: Sequence[str] = (),
        failures: Sequence[str] = (),
        dropped: Sequence[tuple[str, str]] = (),
        checksums: Sequence[str] = (),
    ) -> UnitOutcome:
        return UnitOutcome(
            key=task.key,
            fingerprint=task.fingerprint,
            products=tuple(os.fspath(p) for p in products),
            error=error,
            detail=detail,
            notes=tuple(notes),
            failures=tuple(failures),
            dropped=tuple(dropped),
            checksums=tuple(checksums),
            seconds=time.perf_counter() - t0,
            peak_rss_mib=peak_rss_mib(),
            pid=os.getpid(),
            host=host,
        )

    # a batch process is cwproc's own: the chain's phases may tune its allocator
    memory.tune_allocator()
    with local_dask_scheduler():
        return _process_unit_task(task, outcome)


def _process_unit_task(task: UnitTask, outcome: Callable[..., UnitOutcome]) -> UnitOutcome:
    """Check the unit's inputs against the plan, run it (:func:`cwproc.pipeline.run_unit`,
    as ``cwproc retrieve`` does) and write whatever products it gave."""
    try:
        config = parsed_config(task.config_toml, task.config_source)[0]
        # .hpl data are read once, chunk by chunk, when the unit streams (classification
        # read their headers only); a new file's checksum is taken by that read
        items = [
            read_input(p, config, identify_only=True, checksum=bool(expected))
            for p, expected in zip(task.paths, task.sha256, strict=True)
        ]
        changed = changed_inputs(task, items)
        if changed:
            return outcome(
                error=f"{changed}: changed while the run was going on; "
                f"unit {task.key} will be redone by the next run"
            )
        units = group_units(items)
        if len(units) != 1 or units[0].key != (task.group_key or task.key):
            found = ", ".join(u.key for u in units)
            return outcome(error=f"{task_label(task)}: its inputs now group as {found}")
        units[0].key = task.key  # a logger kept apart from another of its key (34.2)
        result = run_unit(units[0], config)
        written = (
            write_unit_products(units[0], result.products, task.outdir, config)
            if result.products
            else []
        )
        if written and config.output.qc_report:
            result.notes.extend(quality_reports(written, result.failures, result.notes))
    except (InputFileError, ProductError) as exc:
        return outcome(error=str(exc))  # already names the file
    except CwprocError as exc:
        return outcome(error=f"{task_label(task)}: {exc}")
    except Exception as exc:
        return outcome(
            error=f"{task_label(task)}: internal error {type(exc).__name__}: {exc}",
            detail=traceback.format_exc(),
        )
    # inputs whose data could not be read are file failures (the driver records them),
    # not failures of the unit made without them, as when classification reads them whole
    dropped = dropped_inputs(task, units[0])
    failures = [f for f in result.failures if f not in {line for _, line in dropped}]
    return outcome(
        written,
        error="; ".join(failures),
        notes=result.notes,
        failures=failures,
        dropped=dropped,
        checksums=[item.sha256 or "" for item in items],
    )


def changed_inputs(task: UnitTask, items: Sequence[Any]) -> str:
    """The first input of ``task`` that is not what was planned ('' when none): its
    checksum differs from the plan's, or (an input planned without a checksum) its
    size or modification time differ from those it was classified with."""
    signatures = task.signatures or ((None, None),) * len(task.paths)
    for item, expected, planned in zip(items, task.sha256, signatures, strict=True):
        if expected and item.sha256 != expected:
            return os.fspath(item.path)
        if not expected and planned[0] is not None:
            now = tuple(item.signature[2:4]) if item.signature else None
            if now != tuple(planned):
                return os.fspath(item.path)
    return ""


def quality_reports(
    written: Sequence[Path], failures: Sequence[str], notes: Sequence[str]
) -> list[str]:
    """Write ``<product>.qc.json`` beside the products (``[output] qc_report``); a report
    that cannot be written is a note, not a failure of the unit whose products are."""
    from cwproc.pipeline.quality import write_quality_reports

    try:
        write_quality_reports(written, failures, notes)
    except (OSError, CwprocError) as exc:
        return [f"quality report not written: {exc}"]
    return []


def dropped_inputs(task: UnitTask, unit: ProductUnit) -> list[tuple[str, str]]:
    """(path, failure line) of each input of ``task`` that ``unit`` left out when its
    data could not be read (identified by its header, damaged beyond it)."""
    kept = {os.fspath(i.path) for i in unit.inputs}
    dropped = []
    for path in task.paths:
        if path in kept:
            continue
        lines = [f for f in unit.failures if f.startswith(f"{path}:")]
        dropped.append((path, lines[0] if lines else f"{path}: its data could not be read"))
    return dropped


def task_label(task: UnitTask) -> str:
    """How failure lines name a unit: its key and its (first) input file."""
    more = f" and {len(task.paths) - 1} more" if len(task.paths) > 1 else ""
    first = task.paths[0] if task.paths else "no inputs"
    return f"unit {task.key} ({first}{more})"
