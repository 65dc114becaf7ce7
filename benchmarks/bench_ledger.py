"""Cost of the batch ledger at network scale (issue 17.8): per save and per first run.

Prints, for ledgers of 1,000, 10,000 and 50,000 files (one unit per two files):

1. the time of one save after one unit (the journal append, what ``cwproc batch`` does
   after every unit) and of a full snapshot (what it does once per run), in ms;
2. the time of a first ``run_batch`` over that many files with a trivial classify and
   process step (a toy unit costs nothing, so what is measured is discovery, planning
   and the ledger), in s and in ms per file: it should stay flat (linear growth);
3. the load of the ledger that run left (``load_ledger``: snapshot and journal), in ms;
4. a second run after one new file arrived (the daily case: one unit to do), in s, and
   the bytes it wrote to the state folder (issue 34.7: the end of a run rewrote the
   whole snapshot, 6 s at 10,000 files and 15 s at 50,000 on a busy disk).

Times are CPU seconds of this process (``time.process_time``; fsync waits are not
counted), so that a busy machine does not change them; compare runs as ratios.

Run::

    python benchmarks/bench_ledger.py                 # 1k, 10k, 50k
    python benchmarks/bench_ledger.py --sizes 1000 10000
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

from cwproc.batch import (
    FileInfo,
    Ledger,
    UnitOutcome,
    UnitTask,
    config_hash,
    parsed_config,
    record_file,
    record_outcome,
    run_batch,
    save_ledger,
)
from cwproc.batch.records import LEDGER_NAME, STATE_DIR
from cwproc.batch.state import load_ledger
from cwproc.config import Config

CONFIG = Config()


def toy_classify(path: str, config_toml: str, config_source: str = "<batch>") -> FileInfo:
    """A file of the synthetic archive: unit = its pair (no reading beyond stat)."""
    st = os.stat(path)
    index = int(Path(path).stem.split("_")[1])
    return FileInfo(
        path=path,
        size=st.st_size,
        mtime_ns=st.st_mtime_ns,
        status="ok",
        sha256=f"{index:064x}",
        format="toy",
        kind="toy",
        unit=f"toy_{index // 2:06d}",
        start="2024-06-01T00:00:00",
        config_hash=parsed_config(config_toml, config_source)[1],  # as classify_file
    )


def toy_process(task: UnitTask) -> UnitOutcome:
    """A unit that costs nothing and writes nothing."""
    return UnitOutcome(key=task.key, fingerprint=task.fingerprint, pid=os.getpid())


def ledger_of(n_files: int) -> Ledger:
    ledger = Ledger()
    h = config_hash(CONFIG)
    for i in range(n_files):
        info = FileInfo(
            path=f"/archive/lidar/2024/file_{i:06d}.hpl",
            size=180_000,
            mtime_ns=1_700_000_000_000_000_000 + i,
            status="ok",
            sha256=f"{i:064x}",
            format="hpl",
            kind="scan",
            unit=f"streamline_1_{i // 2:06d}",
            start="2024-06-01T00:00:00",
            config_hash=h,
        )
        record_file(ledger, info)
    for u in range(n_files // 2):
        task = UnitTask(
            key=f"streamline_1_{u:06d}",
            kind="scan",
            paths=(f"/archive/lidar/2024/file_{2 * u:06d}.hpl",),
            sha256=(f"{2 * u:064x}",),
            fingerprint=f"{u:064x}",
            config_toml="",
            config_source="",
            outdir="/products",
        )
        outcome = UnitOutcome(key=task.key, fingerprint=task.fingerprint, products=("/p.nc",))
        record_outcome(ledger, task, outcome)
    return ledger


def save_times(n_files: int, folder: Path) -> tuple[float, float]:
    """(journal save after one unit, full snapshot) in ms."""
    path = folder / f"ledger_{n_files}.json"
    ledger = ledger_of(n_files)
    t0 = time.perf_counter()
    save_ledger(ledger, path, compact=True)
    snapshot = time.perf_counter() - t0
    n = 50
    t0 = time.perf_counter()
    for k in range(n):
        task = UnitTask(
            key=f"new_{k}", kind="scan", paths=("/x",), sha256=("0" * 64,), fingerprint="f",
            config_toml="", config_source="", outdir="/products",
        )  # fmt: skip
        record_outcome(ledger, task, UnitOutcome(key=task.key, fingerprint="f"))
        save_ledger(ledger, path)
    journal = (time.perf_counter() - t0) / n
    return journal * 1e3, snapshot * 1e3


def first_run(n_files: int, folder: Path) -> float:
    archive = folder / f"archive_{n_files}"
    for i in range(n_files):
        sub = archive / f"d{i // 1000:03d}"
        sub.mkdir(parents=True, exist_ok=True)
        (sub / f"f_{i:06d}.toy").write_bytes(b"x")
    t0 = time.process_time()
    report = run_batch(
        archive, folder / f"out_{n_files}", CONFIG, classify=toy_classify, process=toy_process
    )
    seconds = time.process_time() - t0
    assert report.ok and len(report.processed) == (n_files + 1) // 2
    return seconds


def state_bytes(state: Path) -> dict[str, tuple[int, int]]:
    """``{name: (size, mtime_ns)}`` of the files of a state folder."""
    return {p.name: (p.stat().st_size, p.stat().st_mtime_ns) for p in state.iterdir()}


def load_and_rerun(n_files: int, folder: Path) -> tuple[float, float, int]:
    """(load ms, second-run s, bytes written to the state folder by the second run)."""
    out = folder / f"out_{n_files}"
    ledger_path = out / STATE_DIR / LEDGER_NAME
    t0 = time.process_time()
    ledger = load_ledger(ledger_path)
    load = time.process_time() - t0
    assert len(ledger.units) == (n_files + 1) // 2
    (folder / f"archive_{n_files}" / "d000" / f"f_{n_files + 1:06d}.toy").write_bytes(b"x")
    before = state_bytes(out / STATE_DIR)
    t0 = time.process_time()
    report = run_batch(
        folder / f"archive_{n_files}", out, CONFIG, classify=toy_classify, process=toy_process
    )
    rerun = time.process_time() - t0
    assert report.ok and len(report.processed) == 1
    after = state_bytes(out / STATE_DIR)
    written = 0
    for name, (size, mtime) in after.items():
        old_size, old_mtime = before.get(name, (0, None))
        if name == "lock" or mtime == old_mtime:
            continue
        # the journal grows by appends; the snapshot is rewritten whole
        written += size - old_size if name.endswith(".journal") else size
    return load * 1e3, rerun, written


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[1000, 10_000, 50_000])
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        print(f"{'files':>8s} {'save/unit ms':>13s} {'snapshot ms':>12s} "
              f"{'first run s':>12s} {'ms/file':>8s} {'load ms':>8s} "
              f"{'rerun s':>8s} {'rerun bytes':>12s}")  # fmt: skip
        for n in args.sizes:
            journal_ms, snapshot_ms = save_times(n, folder)
            seconds = first_run(n, folder)
            load_ms, rerun_s, written = load_and_rerun(n, folder)
            print(
                f"{n:8d} {journal_ms:13.3f} {snapshot_ms:12.1f} {seconds:12.2f} "
                f"{seconds / n * 1e3:8.3f} {load_ms:8.1f} {rerun_s:8.2f} {written:12d}",
                flush=True,
            )


if __name__ == "__main__":
    main()
