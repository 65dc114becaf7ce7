"""Planning and running a batch: discover, classify, plan, process, record."""

from __future__ import annotations

import dataclasses
import datetime as _dt
import json
import logging
import os
import time
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path, PurePosixPath
from typing import Any

from cwproc.batch.executors import run_tasks
from cwproc.batch.records import (
    LEDGER_NAME,
    LOCK_NAME,
    STATE_DIR,
    BatchReport,
    FileInfo,
    UnitOutcome,
    UnitTask,
    config_hash,
    kv_line,
    unit_fingerprint,
)
from cwproc.batch.state import (
    Ledger,
    cached_file_info,
    forget_vanished_files,
    load_ledger,
    output_lock,
    record_file,
    record_outcome,
    remove_leftover_temporaries,
    save_ledger,
    unit_up_to_date,
)
from cwproc.batch.worker import (
    classify_batch,
    classify_file,
    file_size_mtime,
    process_unit_task,
    unclassified,
)
from cwproc.config import Config
from cwproc.errors import CwprocError
from cwproc.pipeline.product_units import distinct_keys

log = logging.getLogger("cwproc.batch")
log.addHandler(logging.NullHandler())  # a library: the application decides where logs go

#: while classifying many new files, save the ledger at least this often (s)
CLASSIFY_SAVE_INTERVAL_S = 30.0
#: times a task the cluster could not run (worker lost, exception) is submitted again
#: within the run before it counts as failed (:func:`cwproc.batch.executors.run_tasks`)
TASK_RETRIES = 2
#: most files classified by one task (:func:`classification_batches`)
CLASSIFY_BATCH_FILES = 2000
#: fewest classification tasks of a run with that many files
CLASSIFY_MIN_BATCHES = 64


def matches_patterns(relpath: PurePosixPath, patterns: Sequence[str]) -> bool:
    """Whether a path relative to INPUT_DIR matches one of the glob patterns.

    A pattern without ``/`` matches the file name (``*.hpl``); one with ``/`` matches
    the end of the relative path (``2024/*/*.hpl``).
    """
    return any(relpath.match(p) for p in patterns)


def discover_files(
    input_dir: str | os.PathLike,
    patterns: Sequence[str] = ("*",),
    exclude: Sequence[str | os.PathLike] = (),
    errors: list[str] | None = None,
) -> list[Path]:
    """Regular files under ``input_dir`` matching ``patterns``, sorted.

    Hidden files and folders (name starting with ``.``) and the folders in ``exclude``
    (e.g. the output directory when it lies inside the input directory) are skipped.
    Symbolic links to files are followed, links to folders are not. A folder that
    cannot be listed is reported in ``errors`` (one line each), never skipped silently.
    """
    root = Path(input_dir)
    excluded = {os.path.realpath(p) for p in exclude}
    found: list[Path] = []

    def unreadable(exc: OSError) -> None:
        if errors is not None:
            errors.append(f"{exc.filename}: cannot list folder: {exc.strerror or exc}")

    for dirpath, dirnames, filenames in os.walk(root, onerror=unreadable):
        dirnames[:] = sorted(
            d
            for d in dirnames
            if not d.startswith(".") and os.path.realpath(os.path.join(dirpath, d)) not in excluded
        )
        for name in filenames:
            if name.startswith("."):
                continue
            path = Path(dirpath) / name
            rel = PurePosixPath(path.relative_to(root).as_posix())
            if matches_patterns(rel, patterns) and path.is_file():
                found.append(path)
    return sorted(found)


def plan_units(
    infos: Iterable[FileInfo],
    config: Config,
    outdir: str | os.PathLike,
    notes: list[str] | None = None,
) -> list[tuple[UnitTask, str]]:
    """Group classified files into unit tasks, in a stable order.

    Returns ``(task, start)`` pairs; ``start`` is the first sample time of the unit
    (ISO 8601, "" when unknown). Inputs within a unit are sorted by path. Sonic files
    that share a unit key but not their logger's identity are kept apart as
    :func:`cwproc.pipeline.group_units` keeps them (the note in ``notes``).
    """
    by_key: dict[tuple[str, str], list[FileInfo]] = {}
    for info in infos:
        if info.status == "ok":
            by_key.setdefault((info.kind, info.unit), []).append(info)
    groups: dict[tuple[str, str, str], list[FileInfo]] = {}
    for (kind, key), members in by_key.items():
        identities = [_identity(i)[0] for i in members]
        keys, note = distinct_keys(key, identities, [_identity(i)[1] for i in members])
        if note and notes is not None:
            notes.append(note)
        for info, identity in zip(members, identities, strict=True):
            groups.setdefault((kind, keys.get(identity, key), key), []).append(info)
    cfg_hash = config_hash(config)
    toml = config.to_toml()
    out = []
    for (kind, key, group_key), members in sorted(groups.items()):
        members = sorted(members, key=lambda i: i.path)
        task = UnitTask(
            key=key,
            group_key="" if group_key == key else group_key,
            kind=kind,
            paths=tuple(i.path for i in members),
            sha256=tuple(i.sha256 for i in members),
            fingerprint=planned_fingerprint([i.sha256 for i in members], cfg_hash),
            signatures=tuple((i.size, i.mtime_ns) for i in members),
            config_toml=toml,
            config_source=config.source,
            outdir=os.fspath(outdir),
        )
        starts = [i.start for i in members if i.start]
        out.append((task, min(starts) if starts else ""))
    return out


def planned_fingerprint(checksums: Sequence[str], cfg_hash: str) -> str:
    """The fingerprint of a planned unit: :func:`unit_fingerprint`, or "" when an input's
    checksum is not known yet (a new file: its unit takes it, so the unit is never
    found up to date before it is run)."""
    return unit_fingerprint(checksums, cfg_hash) if all(checksums) else ""


def classification_batches(
    items: Sequence[tuple[str, str]],
    max_files: int = CLASSIFY_BATCH_FILES,
    min_batches: int = CLASSIFY_MIN_BATCHES,
) -> list[tuple[tuple[str, str], ...]]:
    """``items`` cut into consecutive batches for :func:`cwproc.batch.worker.classify_batch`.

    At most ``max_files`` a batch, so that a lidar-year (about 700,000 files) is planned
    in a few hundred tasks, not one per file; and at least ``min_batches`` batches (when
    there are that many files), so that the first run of a small archive still spreads
    over a cluster's workers. Consecutive in the discovery order (sorted paths): the
    files of an instrument-day, usually one folder, go to the same batch.
    """
    n = len(items)
    if n == 0:
        return []
    size = max(1, min(int(max_files), -(-n // max(int(min_batches), 1))))
    return [tuple(items[i : i + size]) for i in range(0, n, size)]


def _identity(info: FileInfo) -> tuple[tuple[tuple[str, str], ...], tuple[str, str]]:
    """The logger identity and time span a classification stored (empty when none)."""
    if not info.identity:
        return (), ("", "")
    stored = json.loads(info.identity)
    first, last = stored["span"]
    return tuple((str(k), str(v)) for k, v in stored["fields"]), (str(first), str(last))


def before_since(start: str, since: _dt.date | None) -> bool:
    """Whether a unit whose data begin at ``start`` (ISO) lies before ``--since``.

    Units without a time are never skipped.
    """
    if since is None or not start:
        return False
    return start[:10] < since.isoformat()


def file_older_than(mtime_ns: int, since: _dt.date | None) -> bool:
    """Whether a file was last modified before 00:00 UTC of ``since``.

    Such a file holds only data from before that day (a file is written after the
    data it holds), so no unit of ``since`` or later can include it.
    """
    if since is None:
        return False
    midnight = _dt.datetime.combine(since, _dt.time(), tzinfo=_dt.UTC)
    return mtime_ns < int(midnight.timestamp()) * 1_000_000_000


def run_batch(
    input_dir: str | os.PathLike,
    outdir: str | os.PathLike,
    config: Config,
    *,
    patterns: Sequence[str] = ("*",),
    since: _dt.date | None = None,
    min_age_s: float = 0.0,
    client: Any = None,
    wait_s: float = 0.0,
    classify: Callable[[str, str, str], FileInfo] = classify_file,
    process: Callable[[UnitTask], UnitOutcome] = process_unit_task,
    on_plan: Callable[[int], None] | None = None,
    on_unit: Callable[[UnitOutcome], None] | None = None,
) -> BatchReport:
    """Process every new or changed product unit under ``input_dir`` into ``outdir``.

    Parameters
    ----------
    input_dir, outdir : path
        The archive (searched recursively) and the product directory.
    config : Config
        The configuration (its hash is part of every unit's fingerprint).
    patterns : sequence of str
        Glob patterns of the files to consider (see :func:`matches_patterns`).
    since : datetime.date, optional
        Process only units whose data begin on or after this UTC day; files modified
        before it are not even read.
    min_age_s : float
        Leave files modified less than this many seconds ago (still being written by
        the instrument) for a later run.
    client : dask.distributed.Client, optional
        Run classification and units on this cluster; ``None`` runs them here.
    wait_s : float
        How long to wait for the lock held by another run (s).
    classify, process : callables
        Worker-side functions (defaults: :func:`classify_file`,
        :func:`process_unit_task`); top-level functions so that Dask can ship them.
    on_plan, on_unit : callables, optional
        Called with the number of units to process, and after each unit.

    Returns
    -------
    BatchReport

    Raises
    ------
    LockBusyError
        Another run holds the output directory.
    CwprocError
        The input directory does not exist, or the ledger cannot be read or written.
    """
    t0 = time.perf_counter()
    input_dir, outdir = checked_folders(input_dir, outdir)
    state_dir = outdir / STATE_DIR
    ledger_path = state_dir / LEDGER_NAME
    report = BatchReport(pinned_format=config.instrument.format)
    with output_lock(state_dir, wait_s=wait_s) as stale:
        _note_stale_lock_and_leftovers(stale, state_dir, outdir, report)
        run = _RunLedger(load_ledger(ledger_path), ledger_path, config_hash(config), report)
        infos, todo = _plan_run(
            run, input_dir, outdir, config, patterns, since, min_age_s, classify, client
        )
        if on_plan is not None:
            on_plan(len(todo))
        _run_units(run, process, todo, infos, client, on_unit)
        run.save()  # the last changes; compacted only periodically
    report.seconds = time.perf_counter() - t0
    return report


def _note_stale_lock_and_leftovers(
    stale: Any, state_dir: Path, outdir: Path, report: BatchReport
) -> None:
    """Log a lock left by a killed run (kept in ``report``) and remove the temporaries
    of unfinished writes in ``outdir``."""
    report.stale_lock = stale
    if stale:
        log.warning(kv_line("stale_lock", lock=state_dir / LOCK_NAME, previous=stale))
    for path in remove_leftover_temporaries(outdir):
        log.warning(kv_line("removed_temporary", path=path))


@dataclasses.dataclass(frozen=True)
class _RunLedger:
    """The ledger of a batch run, the file it is saved to, the configuration's hash
    (part of every fingerprint) and the run's report."""

    ledger: Ledger
    path: Path
    cfg_hash: str
    report: BatchReport

    def save(self) -> None:
        """Write the ledger to its file (atomically, :func:`save_ledger`)."""
        save_ledger(self.ledger, self.path)


def _plan_run(
    run: _RunLedger,
    input_dir: Path,
    outdir: Path,
    config: Config,
    patterns: Sequence[str],
    since: _dt.date | None,
    min_age_s: float,
    classify: Callable[[str, str, str], FileInfo],
    client: Any,
) -> tuple[list[FileInfo], list[UnitTask]]:
    """The files of the archive (classified: from the ledger or anew) and the units to
    process; the ledger saved when classification changed it."""
    ledger, report = run.ledger, run.report
    files = discover_files(input_dir, patterns, exclude=[outdir], errors=report.listing_failures)
    for line in report.listing_failures:
        log.warning(kv_line("folder", status="failed", error=line))
    report.discovered = len(files)
    infos, to_classify = _cached_or_new(files, ledger, run.cfg_hash, since, min_age_s, report)
    infos += _classify_new(to_classify, classify, config, client, ledger, run.path)
    if forget_vanished_files(ledger) or to_classify:
        run.save()
    _sort_files(infos, report)
    planned = plan_units(infos, config, outdir, report.plan_notes)
    todo = _units_to_do(planned, ledger, since, report)
    log.info(
        kv_line(
            "plan",
            files=len(files),
            classified=len(to_classify),
            units=len(planned),
            todo=len(todo),
            up_to_date=report.units_up_to_date,
        )
    )
    return infos, todo


def _run_units(
    run: _RunLedger,
    process: Callable[[UnitTask], UnitOutcome],
    todo: list[UnitTask],
    infos: list[FileInfo],
    client: Any,
    on_unit: Callable[[UnitOutcome], None] | None,
) -> None:
    """Process the units to do (here or on ``client``), recording each outcome in the
    ledger as it arrives (saved after each unit) and in the run's report."""
    ledger, report, cfg_hash = run.ledger, run.report, run.cfg_hash
    by_path = {i.path: i for i in infos}
    for task, result in run_tasks(process, todo, client=client, retries=TASK_RETRIES):
        outcome = _as_outcome(task, result)
        task, outcome = with_checksums(task, outcome, ledger, cfg_hash)
        if outcome.dropped:
            task, outcome = _record_dropped(task, outcome, by_path, ledger, report, cfg_hash)
        if not task.paths:  # every input unreadable: no unit, as if classified whole
            run.save()
            continue
        record_outcome(ledger, task, outcome)
        run.save()
        report.processed.append(outcome)
        _log_outcome(task, outcome)
        if on_unit is not None:
            on_unit(outcome)


def checked_folders(input_dir: str | os.PathLike, outdir: str | os.PathLike) -> tuple[Path, Path]:
    """The input and output folders as absolute paths; the output folder created.

    Raises
    ------
    CwprocError
        The input folder does not exist, is the output folder, or the output folder
        cannot be created.
    """
    input_dir = Path(input_dir).absolute()
    outdir = Path(outdir).absolute()
    if not input_dir.is_dir():
        raise CwprocError(f"{input_dir}: input directory does not exist")
    if os.path.realpath(input_dir) == os.path.realpath(outdir):
        raise CwprocError(
            f"{outdir}: the output directory must not be the input directory "
            "(products would be read back as inputs); use a subfolder or another folder"
        )
    try:
        outdir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise CwprocError(f"{outdir}: cannot create: {exc.strerror or exc}") from None
    return input_dir, outdir


def _cached_or_new(
    files: Sequence[Path],
    ledger: Ledger,
    cfg_hash: str,
    since: _dt.date | None,
    min_age_s: float,
    report: BatchReport,
) -> tuple[list[FileInfo], list[str]]:
    """The ledger's classifications still valid, and the files to classify anew.

    Files modified less than ``min_age_s`` ago, and files older than ``since`` that the
    ledger does not know, are counted in ``report`` and left out.
    """
    infos: list[FileInfo] = []
    to_classify: list[str] = []
    settled_ns = time.time_ns() - int(min_age_s * 1e9)
    for path in map(os.fspath, files):
        try:
            size, mtime_ns = file_size_mtime(path)
        except OSError:
            continue  # vanished since discovery
        if min_age_s > 0 and mtime_ns > settled_ns:
            report.files_too_new += 1
            continue
        cached = cached_file_info(ledger, path, size, mtime_ns, cfg_hash)
        if cached is not None:
            infos.append(cached)
        elif file_older_than(mtime_ns, since):
            report.files_before_since += 1
        else:
            to_classify.append(path)
    return infos, to_classify


def _classify_new(
    paths: Sequence[str],
    classify: Callable[[str, str, str], FileInfo],
    config: Config,
    client: Any,
    ledger: Ledger,
    ledger_path: Path,
) -> list[FileInfo]:
    """Classify ``paths`` (on ``client``), recording each in the ledger as it comes and
    saving it at least every :data:`CLASSIFY_SAVE_INTERVAL_S` (a long first run keeps
    its progress)."""
    infos = []
    last_save = time.monotonic()
    items = [(p, classify_mode(ledger.files.get(p))) for p in paths]
    batches = classification_batches(items)
    for batch, result in run_tasks(
        classify_batch,
        batches,
        classify,
        config.to_toml(),
        config.source,
        client=client,
        retries=TASK_RETRIES,
    ):
        for info in _as_file_infos(batch, result):
            infos.append(record_file(ledger, info))  # the ledger's record, not a copy
        if time.monotonic() - last_save > CLASSIFY_SAVE_INTERVAL_S:
            save_ledger(ledger, ledger_path)
            last_save = time.monotonic()
    return infos


def classify_mode(entry: dict[str, Any] | None) -> str:
    """How a file is classified given its ledger entry (:data:`CLASSIFY_MODES`).

    A file that failed before is read whole: one damaged beyond its header then fails
    here again, not in its unit, whose record stands. A file the ledger knew with a
    checksum (changed size or time, or another configuration) is checksummed: if its
    content is the same, its unit is up to date. A new file is classified by its header
    alone; its unit takes its checksum from the bytes it parses (one read in all).
    """
    if entry is None:
        return "header"
    if entry.get("status") == "error":
        return "whole"
    return "checksum" if entry.get("sha256") else "header"


def _sort_files(infos: Sequence[FileInfo], report: BatchReport) -> None:
    """Unrecognised files, files of other formats and file failures into ``report``."""
    for status, name in (
        ("unrecognised", "unrecognised"),
        ("other_format", "other_format"),
        ("error", "file_failures"),
    ):
        setattr(
            report,
            name,
            sorted((i for i in infos if i.status == status), key=lambda i: i.path),
        )
    for info in report.file_failures:
        log.warning(kv_line("file", status="failed", path=info.path, error=info.error))


def _units_to_do(
    planned: Sequence[tuple[UnitTask, str]],
    ledger: Ledger,
    since: _dt.date | None,
    report: BatchReport,
) -> list[UnitTask]:
    """The planned units not before ``since`` and not up to date (both counted)."""
    report.units_total = len(planned)
    todo: list[UnitTask] = []
    for task, start in planned:
        if before_since(start, since):
            report.units_before_since += 1
        elif task.fingerprint and unit_up_to_date(ledger, task):  # "": a checksum to take
            report.units_up_to_date += 1
        else:
            todo.append(task)
    return todo


def _as_file_infos(batch: Sequence[tuple[str, str]], result: Any) -> list[FileInfo]:
    """The records of a classification batch; a batch that could not run (a worker
    lost) is a failure of each of its files, retried by the next run."""
    if isinstance(result, list) and len(result) == len(batch):
        return [
            r if isinstance(r, FileInfo) else unclassified(p, r)
            for (p, _), r in zip(batch, result, strict=True)
        ]
    return [unclassified(path, result) for path, _ in batch]


def with_checksums(
    task: UnitTask, outcome: UnitOutcome, ledger: Ledger, cfg_hash: str
) -> tuple[UnitTask, UnitOutcome]:
    """The task with the checksums its unit took of inputs planned without one (new
    files), recorded in the ledger's classifications, and its fingerprint made from
    them; unchanged when the plan knew every checksum."""
    if all(task.sha256) or len(outcome.checksums) != len(task.paths):
        return task, outcome
    sha = tuple(
        planned or taken for planned, taken in zip(task.sha256, outcome.checksums, strict=True)
    )
    for path, planned, taken in zip(task.paths, task.sha256, outcome.checksums, strict=True):
        entry = ledger.files.record(path)
        if not planned and taken and isinstance(entry, FileInfo) and entry.status == "ok":
            ledger.files.put(dataclasses.replace(entry, sha256=taken))
    fingerprint = planned_fingerprint(sha, cfg_hash)
    task = dataclasses.replace(task, sha256=sha, fingerprint=fingerprint)
    return task, dataclasses.replace(outcome, fingerprint=fingerprint)


def _record_dropped(
    task: UnitTask,
    outcome: UnitOutcome,
    infos: dict[str, FileInfo],
    ledger: Ledger,
    report: BatchReport,
    cfg_hash: str,
) -> tuple[UnitTask, UnitOutcome]:
    """Record the inputs a unit left out (data unreadable beyond a good header) as file
    failures, and the unit as made from the others.

    The ledger and the report then read as if classification had read those files whole
    and found the problem: the unit's inputs and fingerprint are those of the files kept,
    so the next run finds it up to date while the damaged files stay unchanged.
    """
    gone = dict(outcome.dropped)
    for path, line in outcome.dropped:
        info = infos.get(path)
        if info is None:
            continue
        failed = dataclasses.replace(
            info, status="error", sha256="", kind="", unit="", start="", error=line
        )
        record_file(ledger, failed)
        report.file_failures.append(failed)
        log.warning(kv_line("file", status="failed", path=path, error=line))
    report.file_failures.sort(key=lambda i: i.path)
    kept = [(p, h) for p, h in zip(task.paths, task.sha256, strict=True) if p not in gone]
    fingerprint = planned_fingerprint([h for _, h in kept], cfg_hash)
    task = dataclasses.replace(
        task,
        paths=tuple(p for p, _ in kept),
        sha256=tuple(h for _, h in kept),
        fingerprint=fingerprint,
    )
    return task, dataclasses.replace(outcome, fingerprint=fingerprint)


def _as_outcome(task: UnitTask, result: Any) -> UnitOutcome:
    if isinstance(result, UnitOutcome):
        return result
    return UnitOutcome(
        key=task.key,
        fingerprint=task.fingerprint,
        error=f"unit {task.key}: the cluster could not run it: {type(result).__name__}: {result}",
    )


def _log_outcome(task: UnitTask, outcome: UnitOutcome) -> None:
    fields: dict[str, Any] = {
        "unit": task.key,
        "status": "ok" if outcome.ok else "failed",
        "inputs": len(task.paths),
        "seconds": f"{outcome.seconds:.3f}",
        "peak_rss_mib": f"{outcome.peak_rss_mib:.1f}",
        "worker": f"{outcome.host}:{outcome.pid}",
    }
    if outcome.ok:
        fields["products"] = ",".join(os.path.basename(p) for p in outcome.products)
        log.info(kv_line("unit", **fields))
    else:
        fields["error"] = outcome.error
        log.warning(kv_line("unit", **fields))
        if outcome.detail:
            log.debug(outcome.detail)
