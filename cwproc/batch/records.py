"""Records exchanged between the driver and the workers (plain, picklable), and small helpers."""

from __future__ import annotations

import datetime as _dt
import functools
import hashlib
import json
from collections.abc import Iterable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from cwproc.config import Config, config_from_toml
from cwproc.errors import CwprocError
from cwproc.pipeline import no_input_of_format, other_formats_note

#: folder inside OUTPUT_DIR that holds the ledger and the lock
STATE_DIR = ".cwproc"
LEDGER_NAME = "ledger.json"
LOCK_NAME = "lock"
LEDGER_VERSION = 1
#: exit status of ``cwproc batch`` when another run holds the lock (sysexits EX_TEMPFAIL)
EXIT_LOCKED = 75


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


@dataclass(frozen=True, slots=True)
class FileInfo:
    """What the classification of one input file found.

    Slotted: a lidar-year's plan holds 700,800 of them (150 bytes each, not 500).

    ``status`` is ``"ok"`` (read; ``kind``/``unit``/``start`` set), ``"unrecognised"``
    (not a format cwproc reads, a cwproc product or a background file; ``error`` says
    why), ``"other_format"`` (a format cwproc reads but the configuration does not, as
    :func:`cwproc.pipeline.format_mismatch` words it) or ``"error"`` (a recognised file
    that cannot be read; ``error`` names the file, the line and the problem).
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
    #: what identifies a sonic file's logger, JSON ``{"fields": [[field, value], ...],
    #: "span": [first, last]}`` (station, serial, program, table, folder:
    #: ``cwproc.pipeline.sonic_identity``; its times: ``sonic_span``); "" else
    identity: str = ""


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
    #: the key its inputs group under alone (:func:`cwproc.pipeline.group_units`) when
    #: ``key`` keeps it apart from another logger of that key; "" when the same
    group_key: str = ""
    #: (size, mtime_ns) of each input when it was classified; an input whose checksum
    #: is "" (new: classified by its header alone) must still have them when its unit
    #: reads it, which takes its checksum (:func:`cwproc.batch.worker.process_unit_task`)
    signatures: tuple[tuple[int, int], ...] = ()


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
    #: one line per failure of the unit (``error`` joins them)
    failures: tuple[str, ...] = ()
    #: (path, failure line) of inputs identified by their header when classified but
    #: whose data could not be read: left out of the unit's products, file failures
    dropped: tuple[tuple[str, str], ...] = ()
    #: SHA-256 of each input (the task's order) from the bytes the unit parsed; "" for
    #: an input it did not read (the driver completes the plan's checksums with them)
    checksums: tuple[str, ...] = ()

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
    #: files of a format cwproc reads but the configuration does not (skipped)
    other_format: list[FileInfo] = field(default_factory=list)
    #: the format the configuration reads ("auto": any)
    pinned_format: str = "auto"
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
    #: notes of the plan (loggers that share a unit key kept apart)
    plan_notes: list[str] = field(default_factory=list)

    @property
    def failed(self) -> list[UnitOutcome]:
        return [o for o in self.processed if not o.ok]

    @property
    def succeeded(self) -> list[UnitOutcome]:
        return [o for o in self.processed if o.ok]

    @property
    def ok(self) -> bool:
        return (
            not self.listing_failures
            and not self.file_failures
            and not self.failed
            and not self.nothing_readable()
        )

    def nothing_readable(self) -> str:
        """Why the run failed when every input is of another format ('' otherwise).

        The line and the exit status are those of ``cwproc retrieve`` on the same files
        (:func:`cwproc.pipeline.no_input_of_format`).
        """
        if not self.other_format or self.units_total or self.file_failures:
            return ""
        return no_input_of_format(len(self.other_format), self.pinned_format)

    def failure_lines(self) -> list[str]:
        """One line per unlisted folder, failed input file or unit (file, line, problem)."""
        nothing = self.nothing_readable()
        return (
            self.listing_failures
            + [f.error for f in self.file_failures]
            + [line for o in self.failed for line in (o.failures or (o.error,))]
            + ([nothing] if nothing else [])
        )

    def notes(self) -> list[str]:
        """What the user should know that is not a failure: one line for the files
        skipped for their format, then the notes of every unit processed (each names its files)."""
        skipped = (
            [
                other_formats_note(
                    [i.path for i in self.other_format],
                    [i.format for i in self.other_format],
                    self.pinned_format,
                )
            ]
            if self.other_format
            else []
        )
        return skipped + self.plan_notes + [line for o in self.processed for line in o.notes]


#: ``FileInfo.format`` of a cwproc product found among the inputs (status unrecognised)
PRODUCT_FORMAT = "cwproc product"


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
