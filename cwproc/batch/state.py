"""The state of an output directory: the ledger of what earlier runs did, and the lock."""

from __future__ import annotations

import contextlib
import errno
import fcntl
import json
import os
import socket
import time
from collections.abc import Iterable, Iterator, Mapping, MutableMapping
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Any

from cwproc.batch.records import (
    LEDGER_NAME,
    LEDGER_VERSION,
    LOCK_NAME,
    STATE_DIR,
    FileInfo,
    LockBusyError,
    UnitOutcome,
    UnitTask,
    utc_now_iso,
)
from cwproc.errors import CwprocError
from cwproc.io.netcdf import umask_mode, write_bytes_atomic


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


#: the fields of a file's ledger entry, in order (those of :class:`FileInfo`)
FILE_FIELDS = tuple(f.name for f in fields(FileInfo))
_FILE_FIELD_SET = frozenset(FILE_FIELDS)
#: the fields of a file's entry that take few distinct values over an archive
_SHARED_FIELDS = ("status", "format", "kind", "unit", "config_hash")
#: entries of the ``files`` table per JSON chunk of a snapshot (:func:`_snapshot_chunks`)
SNAPSHOT_CHUNK = 10_000


class FileTable(MutableMapping[str, dict[str, Any]]):
    """The ledger's ``files`` table, ``{path: FileInfo as dict}``, held compactly.

    A lidar-year is 700,800 entries. Held as one dict per file (12 keys, 650 bytes)
    beside the plan's :class:`FileInfo` records, they cost the driver about 1 KiB a
    file (1.45 GiB with the snapshot's text). Here an entry with exactly FileInfo's
    fields is kept as the :class:`FileInfo` itself (slots: 150 bytes), its few-valued
    strings (status, format, kind, unit, configuration hash) interned, so that all the
    entries of a day share one copy of each; the plan's records are these same objects
    (:meth:`put`, :meth:`record`). Any other entry (another version's) is kept as given.

    Reading an entry (``table[path]``) gives a new dict; :meth:`record` gives the
    stored record without a copy. Like the other tables, the keys set or removed since
    the last save are in ``changed``.
    """

    def __init__(
        self,
        entries: Mapping[str, Any] | Iterable[tuple[str, Any]] = (),
        strings: dict[str, str] | None = None,
    ) -> None:
        self._rows: dict[str, FileInfo | dict[str, Any]] = {}
        self._strings: dict[str, str] = {} if strings is None else strings
        self.changed: set[str] = set()
        for key, value in dict(entries).items():
            self._rows[key] = self.compact(value)

    def compact(self, value: Any) -> FileInfo | dict[str, Any]:
        """The stored form of an entry: a :class:`FileInfo` with interned strings, or,
        for an entry of another shape, a copy of the dict."""
        pool = self._strings
        if isinstance(value, FileInfo):
            shared = [getattr(value, f) for f in _SHARED_FIELDS]
            interned = [pool.setdefault(v, v) if isinstance(v, str) else v for v in shared]
            if all(a is b for a, b in zip(shared, interned, strict=True)):
                return value
            return replace(value, **dict(zip(_SHARED_FIELDS, interned, strict=True)))
        if isinstance(value, Mapping) and value.keys() == _FILE_FIELD_SET:
            return self._from_fields(dict(value))
        return dict(value)

    def _from_fields(self, fields_: dict[str, Any]) -> FileInfo:
        """The record of an entry's fields (``fields_`` is changed: strings interned)."""
        pool = self._strings
        for name in _SHARED_FIELDS:
            text = fields_[name]
            if type(text) is str:
                fields_[name] = pool.setdefault(text, text)
        return FileInfo(**fields_)

    def json_hook(self, obj: dict[str, Any]) -> Any:
        """``object_hook`` of :func:`json.loads`: a file entry compacted as it is parsed
        (a year's snapshot never exists as 700,800 dicts)."""
        return self._from_fields(obj) if obj.keys() == _FILE_FIELD_SET else obj

    def put(self, info: FileInfo) -> FileInfo:
        """Store ``info`` under its path; the stored record (interned strings)."""
        stored = self.compact(info)
        self._rows[info.path] = stored
        self.changed.add(info.path)
        return stored  # type: ignore[return-value]

    def record(self, key: str) -> FileInfo | dict[str, Any] | None:
        """The stored entry of ``key`` (no copy; a dict only for another version's)."""
        return self._rows.get(key)

    def plain(self, key: str) -> dict[str, Any]:
        """The entry of ``key`` as a JSON-ready dict (KeyError when absent)."""
        row = self._rows[key]
        if isinstance(row, FileInfo):
            return {f: getattr(row, f) for f in FILE_FIELDS}
        return dict(row)

    def __getitem__(self, key: str) -> dict[str, Any]:
        return self.plain(key)

    def __setitem__(self, key: str, value: Any) -> None:
        self._rows[key] = self.compact(value)
        self.changed.add(key)

    def __delitem__(self, key: str) -> None:
        del self._rows[key]
        self.changed.add(key)

    def __contains__(self, key: object) -> bool:
        return key in self._rows

    def __iter__(self) -> Iterator[str]:
        return iter(self._rows)

    def __len__(self) -> int:
        return len(self._rows)

    def __repr__(self) -> str:
        return f"FileTable({len(self)} files)"


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
    unit, or at the end of a run, costs the size of the change, not of the ledger; the
    snapshot is compacted when the journal outgrows a quarter of it (:func:`save_ledger`).
    """

    files: FileTable = field(default_factory=FileTable)
    units: dict[str, dict[str, Any]] = field(default_factory=dict)
    failures: dict[str, dict[str, Any]] = field(default_factory=dict)
    #: journal lines on disk since the snapshot
    journal_lines: int = 0

    def __post_init__(self) -> None:
        if not isinstance(self.files, FileTable):
            self.files = FileTable(self.files)
        for name in ("units", "failures"):
            value = getattr(self, name)
            if not isinstance(value, _Tracked):
                setattr(self, name, _Tracked(value))

    def to_json(self) -> str:
        """The snapshot's text (compact JSON: version, files, units, failures)."""
        return b"".join(_snapshot_chunks(self)).decode("utf-8")

    def changes(self) -> list[dict[str, Any]]:
        """The journal entries of the changes since the last save (sorted, JSON-ready)."""
        out = []
        for name in _TABLES:
            table = getattr(self, name)
            for key in sorted(table.changed):
                entry: dict[str, Any] = {"table": name, "key": key}
                if key in table:
                    entry["value"] = table[key]  # a new dict for a file entry
                else:
                    entry["deleted"] = True
                out.append(entry)
        return out

    def changed_count(self) -> int:
        """Entries changed since the last save (the journal lines a save would append)."""
        return sum(len(getattr(self, name).changed) for name in _TABLES)

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
            files = FileTable()  # file entries compacted while parsing (json_hook)
            doc = json.loads(text, object_hook=files.json_hook)
            del text
            if doc.get("version") != LEDGER_VERSION:
                raise ValueError(f"unknown ledger version {doc.get('version')!r}")
            ledger = Ledger(
                files=FileTable(doc.pop("files"), strings=files._strings),
                units=dict(doc["units"]),
                failures=dict(doc["failures"]),
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
    try:  # one parse of all the lines (C speed); line by line only to name a bad one
        text = b"[" + b",".join(complete) + b"]"
        entries = json.loads(text, object_hook=ledger.files.json_hook) if complete else []
    except ValueError:
        entries = None
    if entries is not None and len(entries) == len(complete):
        try:
            _apply_entries(ledger, entries)
            ledger.journal_lines = len(complete)
            return
        except (ValueError, KeyError, TypeError, AttributeError):
            pass  # named below, line by line
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


def _apply_entries(ledger: Ledger, entries: list[Any]) -> None:
    """Apply journal entries in order (ValueError/KeyError/TypeError on a bad one)."""
    tables = {name: getattr(ledger, name) for name in _TABLES}
    for entry in entries:
        table = tables[entry["table"]]
        if entry.get("deleted"):
            table.pop(entry["key"], None)
        else:
            table[entry["key"]] = entry["value"]


def _fsync_folder(folder: Path) -> None:
    dir_fd = os.open(folder, os.O_RDONLY)
    try:
        os.fsync(dir_fd)
    finally:
        os.close(dir_fd)


#: journal lines below which the snapshot is never rewritten (see :func:`save_ledger`)
COMPACT_MIN_LINES = 1000


#: the journal is compacted when longer than this share of the ledger's entries
COMPACT_SHARE = 0.25


def needs_compaction(ledger: Ledger, pending: int = 0) -> bool:
    """Whether the journal, with ``pending`` more lines, would outgrow
    :data:`COMPACT_SHARE` of the ledger (and :data:`COMPACT_MIN_LINES`).

    Then the snapshot is rewritten: each rewrite of ``n`` entries follows at least
    ``n / 4`` appended changes, so saving costs O(1) per change amortised, and a load
    replays at most a quarter of the ledger's entries on top of the snapshot (34.7).
    """
    lines = ledger.journal_lines + pending
    return lines > max(COMPACT_MIN_LINES, COMPACT_SHARE * ledger.size())


def save_ledger(ledger: Ledger, path: str | os.PathLike, *, compact: bool = False) -> None:
    """Save the changes since the last save: appended to the journal, fsynced.

    The cost is that of the change (a unit, a file), not of the ledger, so neither a
    first run over 50,000 files nor the end of a run rewrites the ledger (it was
    rewritten whole once per run: 6 s at 10,000 files, 15 s at 50,000 on a busy disk).
    The snapshot (compact JSON) is rewritten (temporary file, fsync, rename; the journal
    then removed) when there is none yet, when ``compact`` is asked, or periodically
    when :func:`needs_compaction`.

    Raises
    ------
    CwprocError
        The state folder cannot be written.
    """
    path = Path(path)
    journal = journal_path(path)
    try:
        pending = ledger.changed_count()  # the entries are made only to be journalled
        if compact or not path.exists() or needs_compaction(ledger, pending):
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
    """The whole ledger to ``path`` atomically (temporary file, fsync, rename), written
    in chunks (:func:`_snapshot_chunks`): a year's 266 MB never exists as one text."""
    write_bytes_atomic(path, _snapshot_chunks(ledger), fsync=True)


def _snapshot_chunks(ledger: Ledger) -> Iterator[bytes]:
    """The snapshot's compact JSON in pieces of :data:`SNAPSHOT_CHUNK` file entries.

    The bytes are those of ``json.dumps(doc, separators=(",", ":"))`` of the whole
    ``{"version", "files", "units", "failures"}`` document; each chunk of the files
    table is one call of the C encoder on a dict of that many entries.
    """
    compact = {"separators": (",", ":")}
    yield f'{{"version":{json.dumps(LEDGER_VERSION)},"files":{{'.encode()
    files = ledger.files
    keys = list(files)
    for i in range(0, len(keys), SNAPSHOT_CHUNK):
        chunk = {k: files.plain(k) for k in keys[i : i + SNAPSHOT_CHUNK]}
        yield (("," if i else "") + json.dumps(chunk, **compact)[1:-1]).encode("utf-8")
    del keys
    units = json.dumps(dict(ledger.units), **compact)
    failures = json.dumps(dict(ledger.failures), **compact)
    yield f'}},"units":{units},"failures":{failures}}}'.encode()


def cached_file_info(
    ledger: Ledger, path: str, size: int, mtime_ns: int, cfg_hash: str
) -> FileInfo | None:
    """The ledger's classification of ``path`` if still valid, else ``None``.

    Valid means: same size, modification time and configuration, and the file was not a
    failure (failed files are always tried again).
    """
    entry = ledger.files.record(path)
    if entry is None:
        return None
    if isinstance(entry, FileInfo):
        info = entry  # the ledger's own record, shared with the plan (no copy)
    else:  # written by another version of cwproc
        try:
            info = FileInfo(**entry)
        except TypeError:  # classify again
            return None
        if info.kind == "sonic" and "identity" not in entry:
            return None  # classified before loggers were told apart by identity (34.2)
    if (
        info.size != size
        or info.mtime_ns != mtime_ns
        or info.config_hash != cfg_hash
        or info.status == "error"
    ):
        return None
    return info


def record_file(ledger: Ledger, info: FileInfo) -> FileInfo:
    """Store a classification; a file failure also goes to ``failures``.

    Returns the record the ledger keeps (:meth:`FileTable.put`): the plan holds that one,
    not a second copy.
    """
    stored = ledger.files.put(info)
    if info.status == "error":
        previous = ledger.failures.get(info.path, {})
        ledger.failures[info.path] = {
            "error": info.error,
            "attempts": int(previous.get("attempts", 0)) + 1,
            "time": utc_now_iso(),
        }
    else:
        ledger.failures.pop(info.path, None)
    return stored


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
