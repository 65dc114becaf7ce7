"""Incremental, locked, idempotent runs over an archive of instrument files.

``cwproc batch INPUT_DIR OUTPUT_DIR`` is what cron runs every night. It

1. **discovers** inputs anywhere under ``INPUT_DIR`` by their content
   (:func:`cwproc.io.sniff_format`), optionally restricted by glob patterns;
   unrecognised files are counted, not errors; files modified less than ``min_age_s``
   ago (still being written) wait for a later run;
2. **classifies** each new or changed file: reads it once with
   :func:`cwproc.pipeline.read_input` and records its checksum and the product unit it
   belongs to (:func:`cwproc.pipeline.unit_key`, the grouping of ``cwproc retrieve``);
3. **processes** only the units whose fingerprint (SHA-256 of the unit's input
   checksums and of the configuration) is not yet in the ledger, each on its own, with
   :func:`cwproc.pipeline.process_unit` and :func:`cwproc.pipeline.write_unit_products`
   (products are written atomically: temporary file, then rename);
4. records each finished unit in the **ledger** ``OUTPUT_DIR/.cwproc/ledger.json``:
   after every unit its change is appended (fsynced) to ``ledger.json.journal``, and
   the snapshot is rewritten atomically once per run, so a run killed with ``kill -9``
   loses nothing, redoes at most the unit in flight, and a save costs the size of the
   change, not of the ledger. Failures
   are recorded with their reason and retried by the next run;
5. holds an exclusive ``flock`` on ``OUTPUT_DIR/.cwproc/lock`` for the whole run, so
   two runs cannot work on the same output directory. The kernel drops the lock of a
   killed process, so a stale lock file is recognised and taken over.

Work is handed to an *executor*: in-process (serial), a pool of processes on this
machine (``--workers N``, :func:`local_pool`), or a ``dask.distributed`` client
(``--scheduler ADDRESS`` uses an existing cluster). The unit of work is a product unit,
sent as file paths plus the configuration as TOML text (never datasets); outcomes come
back to the driver, which alone touches the ledger. Workers must see the input and
output directories under the same paths as the driver.

The classify and process functions are parameters of :func:`run_batch` (top-level
functions, so that Dask can ship them by reference); the defaults run the cwproc
pipeline.
"""

from __future__ import annotations

import concurrent.futures
import contextlib
import datetime as _dt
import errno
import fcntl
import functools
import hashlib
import json
import logging
import os
import socket
import sys
import time
import traceback
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path, PurePosixPath
from typing import Any

import numpy as np

from cwproc.config import Config, config_from_toml
from cwproc.errors import CwprocError, InputFileError, ProductError
from cwproc.io import Format, is_cwproc_product, sniff_format
from cwproc.io.netcdf import umask_mode, write_bytes_atomic

log = logging.getLogger(__name__)
log.addHandler(logging.NullHandler())  # a library: the application decides where logs go

#: folder inside OUTPUT_DIR that holds the ledger and the lock
STATE_DIR = ".cwproc"
LEDGER_NAME = "ledger.json"
LOCK_NAME = "lock"
LEDGER_VERSION = 1
#: exit status of ``cwproc batch`` when another run holds the lock (sysexits EX_TEMPFAIL)
EXIT_LOCKED = 75

_HEAD_BYTES = 4096
#: while classifying many new files, save the ledger at least this often (s)
CLASSIFY_SAVE_INTERVAL_S = 30.0


class LockBusyError(CwprocError):
    """Another run holds the lock of the output directory."""

    def __init__(self, lock_path: Path, holder: str, waited_s: float) -> None:
        self.lock_path = lock_path
        self.holder = holder
        self.waited_s = waited_s
        waited = f" after waiting {waited_s:g} s" if waited_s > 0 else ""
        super().__init__(
            f"{lock_path}: another cwproc batch run ({holder or 'unknown holder'}) is "
            f"working on this output directory; giving up{waited}"
        )


class DaskNotInstalledError(CwprocError):
    """``--workers``/``--scheduler`` need dask.distributed, which is not installed."""

    def __init__(self) -> None:
        super().__init__(
            'parallel runs need dask.distributed: install it with pip install "cwproc[dask]"'
        )


# --------------------------------------------------------------------------------------
# records exchanged between the driver and the workers (plain, picklable)
# --------------------------------------------------------------------------------------


@dataclass(frozen=True)
class FileInfo:
    """What the classification of one input file found.

    ``status`` is ``"ok"`` (read; ``kind``/``unit``/``start`` set), ``"unrecognised"``
    (not a format cwproc reads, or not the format the configuration pins; ``error``
    says why) or ``"error"`` (a recognised file that cannot be read; ``error`` names
    the file, the line and the problem).
    """

    path: str
    size: int
    mtime_ns: int
    status: str
    sha256: str = ""
    format: str = ""
    kind: str = ""
    unit: str = ""
    #: first sample time of the file, ISO 8601 UTC ("" when the file has no time)
    start: str = ""
    error: str = ""
    #: hash of the configuration the file was classified with (reader options matter)
    config_hash: str = ""


@dataclass(frozen=True)
class UnitTask:
    """One product unit to process: input paths and checksums plus the configuration."""

    key: str
    kind: str
    paths: tuple[str, ...]
    sha256: tuple[str, ...]
    fingerprint: str
    config_toml: str
    config_source: str
    outdir: str


@dataclass(frozen=True)
class UnitOutcome:
    """What processing one unit gave: the products written, or the reason it failed."""

    key: str
    fingerprint: str
    products: tuple[str, ...] = ()
    error: str = ""
    #: traceback of an unexpected (internal) error; empty for input/product errors
    detail: str = ""
    seconds: float = 0.0
    #: peak resident memory of the process that ran the unit so far (MiB)
    peak_rss_mib: float = 0.0
    pid: int = 0
    host: str = ""
    #: what the unit's files gave and products that could not be made (not failures)
    notes: tuple[str, ...] = ()

    @property
    def ok(self) -> bool:
        return not self.error


@dataclass
class BatchReport:
    """Summary of one run."""

    discovered: int = 0
    #: folders under INPUT_DIR that could not be listed (one line each)
    listing_failures: list[str] = field(default_factory=list)
    unrecognised: list[FileInfo] = field(default_factory=list)
    file_failures: list[FileInfo] = field(default_factory=list)
    #: files left for a later run because they were modified less than --min-age ago
    files_too_new: int = 0
    #: files not read because they were last modified before --since
    files_before_since: int = 0
    #: units not processed because their data begin before --since
    units_before_since: int = 0
    units_total: int = 0
    units_up_to_date: int = 0
    processed: list[UnitOutcome] = field(default_factory=list)
    stale_lock: str = ""
    seconds: float = 0.0

    @property
    def failed(self) -> list[UnitOutcome]:
        return [o for o in self.processed if not o.ok]

    @property
    def succeeded(self) -> list[UnitOutcome]:
        return [o for o in self.processed if o.ok]

    @property
    def ok(self) -> bool:
        return not self.listing_failures and not self.file_failures and not self.failed

    def failure_lines(self) -> list[str]:
        """One line per unlisted folder, failed input file or unit (file, line, problem)."""
        return (
            self.listing_failures
            + [f.error for f in self.file_failures]
            + [o.error for o in self.failed]
        )


# --------------------------------------------------------------------------------------
# small pure helpers
# --------------------------------------------------------------------------------------


def utc_now_iso() -> str:
    """The current UTC time as ``YYYY-MM-DDTHH:MM:SSZ``."""
    now = _dt.datetime.now(_dt.UTC).replace(microsecond=0)
    return now.isoformat().replace("+00:00", "Z")


@functools.lru_cache(maxsize=8)
def parsed_config(config_toml: str, config_source: str) -> tuple[Config, str]:
    """The configuration of a run and its :func:`config_hash`, parsed once per process.

    Every file of a run is classified with the same TOML text; parsing and hashing it
    for each file cost about 3 ms (10-40 ms on a loaded machine), more than the rest of
    the classification of a small file. :class:`Config` is frozen, so one parsed copy
    is shared safely.
    """
    config = config_from_toml(config_toml, source=config_source)
    return config, config_hash(config)


def config_hash(config: Config) -> str:
    """SHA-256 of the configuration content (independent of the file it came from)."""
    text = replace(config, source="").to_toml()
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def unit_fingerprint(checksums: Iterable[str], cfg_hash: str) -> str:
    """SHA-256 identifying a unit's work: its input checksums (any order) and the config."""
    digest = hashlib.sha256(cfg_hash.encode("ascii"))
    for checksum in sorted(checksums):
        digest.update(b"\n" + checksum.encode("ascii"))
    return digest.hexdigest()


def kv_line(event: str, **fields: Any) -> str:
    """A structured log line ``event=<event> key=value ...``; values with blanks quoted."""
    parts = [f"event={event}"]
    for key, value in fields.items():
        text = str(value)
        if not text or any(c.isspace() for c in text) or '"' in text or "=" in text:
            text = json.dumps(text)
        parts.append(f"{key}={text}")
    return " ".join(parts)


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


def _first_time_iso(ds: Any) -> str:
    if "time" not in ds.variables:
        return ""
    t = np.asarray(ds["time"].values)
    if not np.issubdtype(t.dtype, np.datetime64):
        return ""
    t = t[~np.isnat(t)]
    if t.size == 0:
        return ""
    return np.datetime_as_string(np.min(t).astype("datetime64[s]"), unit="s") + "Z"


def _file_stat(path: str) -> tuple[int, int]:
    st = os.stat(path)
    return st.st_size, st.st_mtime_ns


# --------------------------------------------------------------------------------------
# worker-side functions (the defaults; run in the driver or on Dask workers)
# --------------------------------------------------------------------------------------


#: ``FileInfo.format`` of a cwproc product found among the inputs (status unrecognised)
PRODUCT_FORMAT = "cwproc product"


def classify_file(path: str, config_toml: str, config_source: str = "<batch>") -> FileInfo:
    """Recognise, checksum and read one file; find the product unit it belongs to.

    Never raises for anything the file can cause: problems come back in the record
    (an unexpected exception of a reader too, so that one file cannot stop a run).

    Parameters
    ----------
    path : str
        The input file.
    config_toml : str
        The configuration as TOML text (:meth:`cwproc.config.Config.to_toml`).
    config_source : str
        Where the configuration came from (recorded in products).
    """
    from cwproc.pipeline import read_input, unit_key

    config, chash = parsed_config(config_toml, config_source)
    try:
        size, mtime_ns = _file_stat(path)
        with open(path, "rb") as fh:
            head = fh.read(_HEAD_BYTES)
    except OSError as exc:
        return FileInfo(path, 0, 0, "error", error=f"{path}: cannot read: {exc.strerror or exc}")
    base = FileInfo(path, size, mtime_ns, "unrecognised", config_hash=chash)
    if not head:
        return replace(base, error=f"{path}: file is empty")
    fmt = sniff_format(head)
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
    pinned = config.instrument.format
    if pinned != "auto" and fmt != Format(pinned):
        return replace(
            base,
            format=fmt.value,
            error=f"{path}: a {fmt.value} file, but the configuration reads only {pinned}",
        )
    try:
        with local_dask_scheduler():
            item = read_input(path, config)
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
    return replace(
        base,
        status="ok",
        sha256=item.sha256,
        format=item.format.value,
        kind=kind,
        unit=key,
        start=_first_time_iso(item.dataset),
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
    ) -> UnitOutcome:
        return UnitOutcome(
            key=task.key,
            fingerprint=task.fingerprint,
            products=tuple(os.fspath(p) for p in products),
            error=error,
            detail=detail,
            notes=tuple(notes),
            seconds=time.perf_counter() - t0,
            peak_rss_mib=peak_rss_mib(),
            pid=os.getpid(),
            host=host,
        )

    with local_dask_scheduler():
        return _process_unit_task(task, outcome)


def _process_unit_task(task: UnitTask, outcome: Callable[..., UnitOutcome]) -> UnitOutcome:
    from cwproc.pipeline import group_units, process_unit, read_input, write_unit_products

    try:
        config = parsed_config(task.config_toml, task.config_source)[0]
        # .hpl data are read once, chunk by chunk, when the unit streams (classification
        # already read them whole and judged them readable)
        items = [read_input(p, config, identify_only=True) for p in task.paths]
        for item, expected in zip(items, task.sha256, strict=True):
            if item.sha256 != expected:
                return outcome(
                    error=f"{item.path}: changed while the run was going on; "
                    f"unit {task.key} will be redone by the next run"
                )
        units = group_units(items)
        if len(units) != 1 or units[0].key != task.key:
            found = ", ".join(u.key for u in units)
            return outcome(error=f"{unit_label(task)}: its inputs now group as {found}")
        notes: list[str] = []
        products = process_unit(units[0], config, notes)
        if units[0].failures:  # readable when classified, not now: redo on the next run
            return outcome(error="; ".join(units[0].failures))
        written = write_unit_products(units[0], products, task.outdir, config)
    except (InputFileError, ProductError) as exc:
        return outcome(error=str(exc))  # already names the file
    except CwprocError as exc:
        return outcome(error=f"{unit_label(task)}: {exc}")
    except Exception as exc:
        return outcome(
            error=f"{unit_label(task)}: internal error {type(exc).__name__}: {exc}",
            detail=traceback.format_exc(),
        )
    return outcome(written, notes=notes)


def unit_label(task: UnitTask) -> str:
    """How failure lines name a unit: its key and its (first) input file."""
    more = f" and {len(task.paths) - 1} more" if len(task.paths) > 1 else ""
    first = task.paths[0] if task.paths else "no inputs"
    return f"unit {task.key} ({first}{more})"


# --------------------------------------------------------------------------------------
# the ledger
# --------------------------------------------------------------------------------------


class _Tracked(dict):
    """A dict that remembers the keys set or removed since the last save of the ledger."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.changed: set[str] = set()

    def __setitem__(self, key: str, value: Any) -> None:
        super().__setitem__(key, value)
        self.changed.add(key)

    def __delitem__(self, key: str) -> None:
        super().__delitem__(key)
        self.changed.add(key)

    def pop(self, key: str, *default: Any) -> Any:
        if key in self:
            self.changed.add(key)
        return super().pop(key, *default)

    def update(self, *args: Any, **kwargs: Any) -> None:
        for key, value in dict(*args, **kwargs).items():
            self[key] = value


#: the tables of the ledger
_TABLES = ("files", "units", "failures")


@dataclass
class Ledger:
    """What earlier runs did, kept in ``OUTPUT_DIR/.cwproc/ledger.json``.

    ``files``: ``{path: FileInfo as dict}`` (classification cache, valid while size,
    mtime and configuration are unchanged); ``units``: ``{unit key: record}`` of units
    whose products were written (fingerprint, inputs, products, time); ``failures``:
    ``{unit key or file path: record}`` of what failed last time and why.

    On disk: a snapshot (``ledger.json``) and an append-only journal of the changes since
    (``ledger.json.journal``, one JSON line per changed entry), so that saving after a
    unit costs the size of the change, not of the ledger (:func:`save_ledger`).
    """

    files: dict[str, dict[str, Any]] = field(default_factory=dict)
    units: dict[str, dict[str, Any]] = field(default_factory=dict)
    failures: dict[str, dict[str, Any]] = field(default_factory=dict)
    #: journal lines on disk since the snapshot
    journal_lines: int = 0

    def __post_init__(self) -> None:
        for name in _TABLES:
            value = getattr(self, name)
            if not isinstance(value, _Tracked):
                setattr(self, name, _Tracked(value))

    def to_json(self) -> str:
        doc = {
            "version": LEDGER_VERSION,
            "files": self.files,
            "units": self.units,
            "failures": self.failures,
        }
        return json.dumps(doc, indent=1, sort_keys=True)

    def changes(self) -> list[dict[str, Any]]:
        """The journal entries of the changes since the last save (sorted, JSON-ready)."""
        out = []
        for name in _TABLES:
            table = getattr(self, name)
            for key in sorted(table.changed):
                entry: dict[str, Any] = {"table": name, "key": key}
                if key in table:
                    entry["value"] = table[key]
                else:
                    entry["deleted"] = True
                out.append(entry)
        return out

    def mark_saved(self) -> None:
        for name in _TABLES:
            getattr(self, name).changed.clear()

    def size(self) -> int:
        return sum(len(getattr(self, name)) for name in _TABLES)


def journal_path(path: str | os.PathLike) -> Path:
    """The journal beside the ledger snapshot ``path``."""
    path = Path(path)
    return path.with_name(path.name + ".journal")


def load_ledger(path: str | os.PathLike) -> Ledger:
    """Read the ledger: the snapshot, then the journal's changes in order.

    An empty ledger when neither exists. A last journal line cut by a kill is ignored
    (its change was never confirmed by the save that wrote it).

    Raises
    ------
    CwprocError
        The ledger is not a cwproc ledger (e.g. edited by hand).
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        text = None
    except OSError as exc:
        raise CwprocError(f"{path}: cannot read the ledger: {exc.strerror or exc}") from None
    ledger = Ledger()
    if text is not None:
        try:
            doc = json.loads(text)
            if doc.get("version") != LEDGER_VERSION:
                raise ValueError(f"unknown ledger version {doc.get('version')!r}")
            ledger = Ledger(
                files=dict(doc["files"]), units=dict(doc["units"]), failures=dict(doc["failures"])
            )
        except (ValueError, KeyError, TypeError, AttributeError) as exc:
            raise CwprocError(
                f"{path}: not a valid cwproc ledger ({exc}); move it away to reprocess everything"
            ) from None
    _replay_journal(ledger, journal_path(path))
    ledger.mark_saved()
    return ledger


def _replay_journal(ledger: Ledger, journal: Path) -> None:
    try:
        lines = journal.read_bytes().split(b"\n")
    except FileNotFoundError:
        return
    except OSError as exc:
        raise CwprocError(f"{journal}: cannot read the ledger: {exc.strerror or exc}") from None
    complete = lines[:-1]  # the part after the last newline was never confirmed
    for number, line in enumerate(complete, start=1):
        try:
            entry = json.loads(line)
            table = getattr(ledger, entry["table"]) if entry["table"] in _TABLES else None
            if table is None:
                raise ValueError(f"unknown table {entry['table']!r}")
            if entry.get("deleted"):
                table.pop(entry["key"], None)
            else:
                table[entry["key"]] = entry["value"]
        except (ValueError, KeyError, TypeError) as exc:
            raise CwprocError(
                f"{journal}:{number}: not a valid ledger journal line ({exc}); "
                "move the ledger files away to reprocess everything"
            ) from None
    ledger.journal_lines = len(complete)


def _fsync_folder(folder: Path) -> None:
    dir_fd = os.open(folder, os.O_RDONLY)
    try:
        os.fsync(dir_fd)
    finally:
        os.close(dir_fd)


def save_ledger(ledger: Ledger, path: str | os.PathLike, *, compact: bool = False) -> None:
    """Save the changes since the last save: appended to the journal, fsynced.

    The cost is that of the change (a unit, a file), not of the ledger, so a first run
    over 50,000 files does not rewrite the ledger 50,000 times. The snapshot is
    rewritten (temporary file, fsync, rename; the journal then removed) when there is
    none yet, when ``compact`` is asked (the end of a run) or when the journal has grown
    longer than the ledger (amortised O(1) per change).

    Raises
    ------
    CwprocError
        The state folder cannot be written.
    """
    path = Path(path)
    journal = journal_path(path)
    try:
        if compact or not path.exists() or ledger.journal_lines > max(1000, ledger.size()):
            _write_snapshot(ledger, path)
            journal.unlink(missing_ok=True)
            _fsync_folder(path.parent)
            ledger.journal_lines = 0
        else:
            entries = ledger.changes()
            if entries:
                data = "".join(json.dumps(e, sort_keys=True) + "\n" for e in entries)
                new = not journal.exists()
                fd = os.open(journal, os.O_WRONLY | os.O_APPEND | os.O_CREAT, umask_mode())
                try:
                    os.write(fd, data.encode("utf-8"))
                    os.fsync(fd)
                finally:
                    os.close(fd)
                if new:
                    _fsync_folder(path.parent)
                ledger.journal_lines += len(entries)
    except OSError as exc:
        raise CwprocError(f"{path}: cannot write the ledger: {exc.strerror or exc}") from None
    ledger.mark_saved()


def _write_snapshot(ledger: Ledger, path: Path) -> None:
    """The whole ledger to ``path`` atomically (temporary file, fsync, rename)."""
    write_bytes_atomic(path, ledger.to_json().encode("utf-8"), fsync=True)


def cached_file_info(
    ledger: Ledger, path: str, size: int, mtime_ns: int, cfg_hash: str
) -> FileInfo | None:
    """The ledger's classification of ``path`` if still valid, else ``None``.

    Valid means: same size, modification time and configuration, and the file was not a
    failure (failed files are always tried again).
    """
    entry = ledger.files.get(path)
    if entry is None:
        return None
    try:
        info = FileInfo(**entry)
    except TypeError:  # written by another version of cwproc: classify again
        return None
    if (
        info.size != size
        or info.mtime_ns != mtime_ns
        or info.config_hash != cfg_hash
        or info.status == "error"
    ):
        return None
    return info


def record_file(ledger: Ledger, info: FileInfo) -> None:
    """Store a classification; a file failure also goes to ``failures``."""
    ledger.files[info.path] = asdict(info)
    if info.status == "error":
        previous = ledger.failures.get(info.path, {})
        ledger.failures[info.path] = {
            "error": info.error,
            "attempts": int(previous.get("attempts", 0)) + 1,
            "time": utc_now_iso(),
        }
    else:
        ledger.failures.pop(info.path, None)


def unit_up_to_date(ledger: Ledger, task: UnitTask) -> bool:
    """Whether the ledger has this unit with the same fingerprint and all its products.

    A product deleted (or moved away) by hand is made again.
    """
    record = ledger.units.get(task.key)
    if record is None or record.get("fingerprint") != task.fingerprint:
        return False
    return all(os.path.isfile(p) for p in record.get("products", ()))


def forget_vanished_files(ledger: Ledger) -> list[str]:
    """Drop the classifications (and file failures) of files that no longer exist."""
    gone = [path for path in ledger.files if not os.path.lexists(path)]
    for path in gone:
        del ledger.files[path]
        ledger.failures.pop(path, None)
    return gone


def record_outcome(ledger: Ledger, task: UnitTask, outcome: UnitOutcome) -> None:
    """Store the outcome of a unit: a success in ``units``, a failure in ``failures``.

    A failed unit gets no ``units`` entry, so the next run processes it again.
    """
    if outcome.ok:
        ledger.units[task.key] = {
            "fingerprint": task.fingerprint,
            "inputs": dict(zip(task.paths, task.sha256, strict=True)),
            "products": list(outcome.products),
            "time": utc_now_iso(),
            "seconds": round(outcome.seconds, 3),
        }
        ledger.failures.pop(task.key, None)
    else:
        ledger.units.pop(task.key, None)
        previous = ledger.failures.get(task.key, {})
        ledger.failures[task.key] = {
            "error": outcome.error,
            "fingerprint": task.fingerprint,
            "attempts": int(previous.get("attempts", 0)) + 1,
            "time": utc_now_iso(),
        }


def remove_leftover_temporaries(outdir: str | os.PathLike) -> list[Path]:
    """Delete temporary files a killed run left in ``outdir`` and its state folder.

    Only names made by cwproc's atomic writers are touched (``.<name>.nc.<random>.tmp``
    from :func:`cwproc.io.netcdf.write_netcdf_atomic`, ``.ledger.json.<random>.tmp``
    from :func:`save_ledger`). Call it only while holding the lock.
    """
    removed = []
    for folder in (Path(outdir), Path(outdir) / STATE_DIR):
        for path in folder.glob(".*.tmp"):
            if (".nc." in path.name or path.name.startswith(f".{LEDGER_NAME}.")) and path.is_file():
                with contextlib.suppress(FileNotFoundError):
                    path.unlink()
                    removed.append(path)
    return removed


# --------------------------------------------------------------------------------------
# the lock
# --------------------------------------------------------------------------------------


def lock_holder_text(pid: int, host: str, started: str) -> str:
    """What the lock file says about its holder."""
    return f"pid={pid} host={host} started={started}"


@contextlib.contextmanager
def output_lock(
    state_dir: str | os.PathLike, wait_s: float = 0.0, poll_s: float = 0.2
) -> Iterator[str]:
    """Hold the exclusive lock of an output directory for the duration of the block.

    The lock is an ``flock`` on ``<state_dir>/lock``; the file names the holder
    (pid, host, start time). The kernel releases the flock of a process that dies, so
    the lock of a killed run is taken over; its leftover holder text is yielded (empty
    when the previous run ended cleanly).

    Parameters
    ----------
    state_dir : path
        ``OUTPUT_DIR/.cwproc`` (created if missing).
    wait_s : float
        How long to wait for another run to finish (s); 0 gives up at once.
    poll_s : float
        Interval between attempts while waiting (s).

    Raises
    ------
    LockBusyError
        Another run still holds the lock after ``wait_s``.
    """
    state = Path(state_dir)
    path = state / LOCK_NAME
    try:
        state.mkdir(parents=True, exist_ok=True)
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    except OSError as exc:
        raise CwprocError(f"{path}: cannot create the lock: {exc.strerror or exc}") from None
    try:
        deadline = time.monotonic() + max(wait_s, 0.0)
        while True:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                break
            except OSError as exc:
                if exc.errno not in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                    raise
                if time.monotonic() >= deadline:
                    holder = os.pread(fd, 4096, 0).decode("utf-8", "replace").strip()
                    raise LockBusyError(path, holder, wait_s) from None
                time.sleep(poll_s)
        stale = os.pread(fd, 4096, 0).decode("utf-8", "replace").strip()
        text = lock_holder_text(os.getpid(), socket.gethostname(), utc_now_iso()) + "\n"
        os.ftruncate(fd, 0)
        os.pwrite(fd, text.encode("utf-8"), 0)
        os.fsync(fd)
        try:
            yield stale
        finally:
            os.ftruncate(fd, 0)
            fcntl.flock(fd, fcntl.LOCK_UN)
    finally:
        os.close(fd)


# --------------------------------------------------------------------------------------
# executors
# --------------------------------------------------------------------------------------


def run_tasks(
    fn: Callable[..., Any], items: Sequence[Any], *args: Any, client: Any = None
) -> Iterator[tuple[Any, Any]]:
    """Run ``fn(item, *args)`` for every item; yield ``(item, result)`` as they finish.

    Without ``client`` the calls run here, one after the other. With a
    :class:`concurrent.futures.Executor` (:func:`local_pool`) or a
    ``dask.distributed.Client`` they are submitted to its processes and yielded in order
    of completion; a task that could not run (worker killed, function not importable
    there) yields the exception as its result.
    """
    if client is None:
        for item in items:
            yield item, fn(item, *args)
        return
    if isinstance(client, concurrent.futures.Executor):
        pending = {client.submit(fn, item, *args): item for item in items}
        for future in concurrent.futures.as_completed(pending):
            item = pending.pop(future)
            try:
                result = future.result()
            except Exception as exc:  # a worker died or the call failed: the unit's result
                result = exc
            yield item, result
        return
    from dask.distributed import as_completed

    futures = {client.submit(fn, item, *args, pure=False): item for item in items}
    for future in as_completed(futures):
        item = futures.pop(future)
        try:
            result = future.result()
        except Exception as exc:
            result = exc
        finally:
            future.release()
        yield item, result


def dask_client(
    workers: int | None = None, scheduler: str | None = None, timeout_s: float = 10.0
) -> Any:
    """A ``dask.distributed.Client``: a new ``LocalCluster`` or an existing scheduler.

    Parameters
    ----------
    workers : int, optional
        Start a LocalCluster of this many worker processes, one thread each.
    scheduler : str, optional
        Address of a running scheduler (``tcp://host:8786``).
    timeout_s : float
        How long to try to reach the scheduler (s).

    Raises
    ------
    DaskNotInstalledError
        dask.distributed is not installed.
    CwprocError
        The scheduler cannot be reached.
    """
    try:
        from dask.distributed import Client, LocalCluster
    except ImportError:
        raise DaskNotInstalledError() from None
    if scheduler:
        try:
            return Client(scheduler, timeout=f"{timeout_s}s")
        except (OSError, TimeoutError) as exc:
            raise CwprocError(f"cannot reach the Dask scheduler {scheduler}: {exc}") from None
    cluster = LocalCluster(
        n_workers=int(workers or 1),
        threads_per_worker=1,
        processes=True,
        dashboard_address=None,
        silence_logs=logging.ERROR,
    )
    return Client(cluster)


def local_pool(workers: int) -> concurrent.futures.ProcessPoolExecutor:
    """A pool of ``workers`` processes on this machine (``--workers N``).

    A process pool rather than a Dask ``LocalCluster``: units take a tenth of a second
    to a few seconds, and a LocalCluster's start (about 2 s) and its cost per task
    (scheduler round trips, about 10 ms) made two workers slower than one on 30 days
    of scans. Workers are forked where the platform allows it (no second import of
    cwproc), else spawned. Dask remains the executor of a cluster (``--scheduler``).
    """
    import multiprocessing

    method = "fork" if "fork" in multiprocessing.get_all_start_methods() else "spawn"
    return concurrent.futures.ProcessPoolExecutor(
        max_workers=int(workers), mp_context=multiprocessing.get_context(method)
    )


def close_client(client: Any) -> None:
    """Close a client and, when it owns one, its LocalCluster (or shut a local pool)."""
    if isinstance(client, concurrent.futures.Executor):
        client.shutdown(wait=True, cancel_futures=True)
        return
    cluster = getattr(client, "cluster", None)
    client.close()
    if cluster is not None:
        cluster.close()


# --------------------------------------------------------------------------------------
# planning and running
# --------------------------------------------------------------------------------------


def plan_units(
    infos: Iterable[FileInfo], config: Config, outdir: str | os.PathLike
) -> list[tuple[UnitTask, str]]:
    """Group classified files into unit tasks, in a stable order.

    Returns ``(task, start)`` pairs; ``start`` is the first sample time of the unit
    (ISO 8601, "" when unknown). Inputs within a unit are sorted by path.
    """
    groups: dict[tuple[str, str], list[FileInfo]] = {}
    for info in infos:
        if info.status == "ok":
            groups.setdefault((info.kind, info.unit), []).append(info)
    cfg_hash = config_hash(config)
    toml = config.to_toml()
    out = []
    for (kind, key), members in sorted(groups.items()):
        members = sorted(members, key=lambda i: i.path)
        task = UnitTask(
            key=key,
            kind=kind,
            paths=tuple(i.path for i in members),
            sha256=tuple(i.sha256 for i in members),
            fingerprint=unit_fingerprint((i.sha256 for i in members), cfg_hash),
            config_toml=toml,
            config_source=config.source,
            outdir=os.fspath(outdir),
        )
        starts = [i.start for i in members if i.start]
        out.append((task, min(starts) if starts else ""))
    return out


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
    state_dir = outdir / STATE_DIR
    ledger_path = state_dir / LEDGER_NAME
    report = BatchReport()
    with output_lock(state_dir, wait_s=wait_s) as stale:
        report.stale_lock = stale
        if stale:
            log.warning(kv_line("stale_lock", lock=state_dir / LOCK_NAME, previous=stale))
        for path in remove_leftover_temporaries(outdir):
            log.warning(kv_line("removed_temporary", path=path))
        ledger = load_ledger(ledger_path)
        cfg_hash = config_hash(config)
        toml = config.to_toml()

        files = discover_files(
            input_dir, patterns, exclude=[outdir], errors=report.listing_failures
        )
        for line in report.listing_failures:
            log.warning(kv_line("folder", status="failed", error=line))
        report.discovered = len(files)
        infos: list[FileInfo] = []
        to_classify: list[str] = []
        settled_ns = time.time_ns() - int(min_age_s * 1e9)
        for path in map(os.fspath, files):
            try:
                size, mtime_ns = _file_stat(path)
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
        last_save = time.monotonic()
        for _path, result in run_tasks(classify, to_classify, toml, config.source, client=client):
            info = _as_file_info(_path, result)
            record_file(ledger, info)
            infos.append(info)
            if time.monotonic() - last_save > CLASSIFY_SAVE_INTERVAL_S:
                save_ledger(ledger, ledger_path)  # a long first run keeps its progress
                last_save = time.monotonic()
        if forget_vanished_files(ledger) or to_classify:
            save_ledger(ledger, ledger_path)

        report.unrecognised = sorted(
            (i for i in infos if i.status == "unrecognised"), key=lambda i: i.path
        )
        report.file_failures = sorted(
            (i for i in infos if i.status == "error"), key=lambda i: i.path
        )
        for info in report.file_failures:
            log.warning(kv_line("file", status="failed", path=info.path, error=info.error))

        planned = plan_units(infos, config, outdir)
        report.units_total = len(planned)
        todo: list[UnitTask] = []
        for task, start in planned:
            if before_since(start, since):
                report.units_before_since += 1
            elif unit_up_to_date(ledger, task):
                report.units_up_to_date += 1
            else:
                todo.append(task)
        if on_plan is not None:
            on_plan(len(todo))
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
        for task, result in run_tasks(process, todo, client=client):
            outcome = _as_outcome(task, result)
            record_outcome(ledger, task, outcome)
            save_ledger(ledger, ledger_path)
            report.processed.append(outcome)
            _log_outcome(task, outcome)
            if on_unit is not None:
                on_unit(outcome)
        if ledger.journal_lines:  # one snapshot per run: ledger.json complete between runs
            save_ledger(ledger, ledger_path, compact=True)
    report.seconds = time.perf_counter() - t0
    return report


def _as_file_info(path: str, result: Any) -> FileInfo:
    if isinstance(result, FileInfo):
        return result
    size, mtime_ns = 0, 0
    with contextlib.suppress(OSError):
        size, mtime_ns = _file_stat(path)
    return FileInfo(
        path, size, mtime_ns, "error", error=f"{path}: could not be classified: {result!r}"
    )


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
