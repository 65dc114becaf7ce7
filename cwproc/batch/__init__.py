"""Incremental, locked, idempotent runs over an archive of instrument files.

``cwproc batch INPUT_DIR OUTPUT_DIR`` is what cron runs every night. It

1. **discovers** inputs anywhere under ``INPUT_DIR`` by their content
   (:func:`cwproc.io.sniff_format`), optionally restricted by glob patterns;
   unrecognised files are counted, not errors; files modified less than ``min_age_s``
   ago (still being written) wait for a later run;
2. **classifies** each new or changed file, in batches of up to 2,000 files a task
   (:func:`cwproc.batch.run.classification_batches`; a lidar-year in a few hundred
   tasks): finds the product unit it belongs to (:func:`cwproc.pipeline.unit_key`,
   the grouping of ``cwproc retrieve``; a ``.hpl`` file from its header alone) and its
   checksum, which for a ``.hpl`` file new to the ledger its unit takes from the bytes
   it parses (each file read once in a run);
3. **processes** only the units whose fingerprint (SHA-256 of the unit's input
   checksums and of the configuration) is not yet in the ledger, each on its own, with
   :func:`cwproc.pipeline.run_unit` (the chain ``cwproc retrieve`` runs: same products,
   notes and failures) and :func:`cwproc.pipeline.write_unit_products` (products are
   written atomically: temporary file, then rename);
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

Modules: ``records`` (what the driver and the workers exchange), ``worker`` (classify
one file, process one unit), ``state`` (ledger and lock), ``executors`` (serial, process
pool, Dask) and ``run`` (:func:`run_batch`).
"""

from cwproc.batch.executors import (
    close_client,
    dask_client,
    local_pool,
    run_tasks,
)
from cwproc.batch.records import (
    EXIT_LOCKED,
    LEDGER_NAME,
    LOCK_NAME,
    PRODUCT_FORMAT,
    STATE_DIR,
    BatchReport,
    DaskNotInstalledError,
    FileInfo,
    LockBusyError,
    UnitOutcome,
    UnitTask,
    config_hash,
    kv_line,
    parsed_config,
    unit_fingerprint,
    utc_now_iso,
)
from cwproc.batch.run import (
    before_since,
    classification_batches,
    discover_files,
    file_older_than,
    matches_patterns,
    plan_units,
    run_batch,
)
from cwproc.batch.state import (
    Ledger,
    cached_file_info,
    forget_vanished_files,
    journal_path,
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
    peak_rss_mib,
    process_unit_task,
)

__all__ = [
    "EXIT_LOCKED",
    "LEDGER_NAME",
    "LOCK_NAME",
    "PRODUCT_FORMAT",
    "STATE_DIR",
    "BatchReport",
    "DaskNotInstalledError",
    "FileInfo",
    "Ledger",
    "LockBusyError",
    "UnitOutcome",
    "UnitTask",
    "before_since",
    "cached_file_info",
    "classification_batches",
    "classify_batch",
    "classify_file",
    "close_client",
    "config_hash",
    "dask_client",
    "discover_files",
    "file_older_than",
    "forget_vanished_files",
    "journal_path",
    "kv_line",
    "load_ledger",
    "local_pool",
    "matches_patterns",
    "output_lock",
    "parsed_config",
    "peak_rss_mib",
    "plan_units",
    "process_unit_task",
    "record_file",
    "record_outcome",
    "remove_leftover_temporaries",
    "run_batch",
    "run_tasks",
    "save_ledger",
    "unit_fingerprint",
    "unit_up_to_date",
    "utc_now_iso",
]
