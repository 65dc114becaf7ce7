"""A lidar-year through ``cwproc batch``: planning at full scale, processing a month.

The year of issue 35: one Stream Line, 180-ray VADs every 45 s with 100 gates (the day
of ``bench_retrieve_day.py``: 1920 files, about 1.2 GB a day), 365 days, 700,800
files. Nothing of the year is stored:

1. **Planning, at full scale, in a child process** (its memory is the driver's):
   the classification records of 700,800 new files are generated on the fly (what
   :func:`cwproc.batch.worker.classify_batch` returns for a file read by its header:
   path, size, time, unit, first ray time, no checksum yet), recorded in a ledger,
   saved (journal, then the snapshot), cut into classification tasks
   (:func:`cwproc.batch.run.classification_batches`) and planned into units
   (:func:`cwproc.batch.run.plan_units`). Printed: the driver's time and peak memory
   (VmHWM above the imports), the ledger's size, the number of tasks. Then the saved
   ledger is loaded in another child (the next run's start): its time and peak memory.
2. **Classification on the workers**, measured on ``--header-files`` real files of the
   year's layout cut after their first ray lines (classification reads a ``.hpl`` file's
   header and first ray only): CPU per file of :func:`classify_batch`, scaled to the
   year.
3. **A month processed**: ``--days`` days (30) of simulated 180-ray VADs of the year's
   size (100 gates, about 630 KB a file), day ``d`` holding the day's first ``--scans``
   x (1, 2, 3)[d % 3] scans (32: 1920 files, 1.2 GB, for the month; the full month of
   57,600 files and 36 GB is more than a shared 2-core machine can write and process in
   a benchmark), as a first run of ``cwproc batch``: an untimed serial run (imports,
   A-tables; the reference products), then timed on a local pool of 1 and 2 workers
   and on a Dask LocalCluster of 2 (last: a pool forked in a process running a
   LocalCluster hangs). The products of every way are compared with the serial run's by
   the SHA-256 of every product variable (values, dimensions, dtype, attributes; the
   global attributes hold creation dates and UUIDs). The time of a full day of 1920
   files on one core is the least-squares line of the month's unit seconds against
   their files (a cost per unit plus a cost per file) at 1920.

The year's wall time on k cores = planning + classification / k + 365 x (day) / (k x
efficiency), with the efficiency of 2 workers measured here (units are independent:
beyond 2, the same efficiency is assumed, the shared file system aside).

Run (small on a loaded machine; compare figures of one run only)::

    OMP_NUM_THREADS=1 python benchmarks/bench_archive_year.py [--days 30] [--scans 32]
    python benchmarks/bench_archive_year.py --plan-only   # the year's planning alone
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import bench_retrieve_day as day_spec

#: the year: 365 days of one VAD file every 45 s
DAYS, FILES_PER_DAY = int(os.environ.get("CWPROC_YEAR_DAYS", "365")), 1920
YEAR_FILES = DAYS * FILES_PER_DAY


def vm_kib(field: str) -> int:
    """``VmHWM`` / ``VmRSS`` of this process (KiB)."""
    with open("/proc/self/status", encoding="ascii") as fh:
        for line in fh:
            if line.startswith(field + ":"):
                return int(line.split()[1])
    return 0


def file_name(day: int, k: int) -> str:
    """``/archive/2024/MM/DD/VAD_999_YYYYMMDD_HHMMSS.hpl`` of scan ``k`` of ``day``."""
    t = np.datetime64("2024-01-01T00:00:00", "s") + np.timedelta64(day * 86400 + k * 45, "s")
    stamp = str(t).replace("-", "").replace(":", "")
    folder = str(t)[:10].replace("-", "/")
    return f"/archive/{folder}/VAD_999_{stamp[:8]}_{stamp[9:15]}.hpl"


def plan_year(out: Path) -> dict[str, float]:
    """Step 1 in this process: the year's records generated, recorded, saved, planned."""
    from cwproc.batch import FileInfo, Ledger, config_hash, plan_units, record_file, save_ledger
    from cwproc.batch.run import classification_batches
    from cwproc.config import Config

    config = Config()
    chash = config_hash(config)
    base_kib = vm_kib("VmRSS")
    t0 = time.perf_counter()
    c0 = time.process_time()
    ledger = Ledger()
    infos = []
    size = 180 * (day_spec.GATES + 1) * 35  # bytes of a file of the year (about)
    for day in range(DAYS):
        date = str(np.datetime64("2024-01-01") + np.timedelta64(day, "D")).replace("-", "")
        unit = f"streamline_999_{date}"
        for k in range(FILES_PER_DAY):
            path = file_name(day, k)
            start = path[-19:-4]
            info = FileInfo(
                path,
                size,
                1_700_000_000_000_000_000 + k,
                "ok",
                format="hpl",
                kind="scan",
                unit=unit,
                start=f"{start[:4]}-{start[4:6]}-{start[6:8]}T{start[9:11]}:{start[11:13]}:"
                f"{start[13:15]}Z",
                config_hash=chash,
            )
            infos.append(record_file(ledger, info))  # the ledger's record, as run_batch
    t_records = time.perf_counter() - t0
    batches = classification_batches([(i.path, "header") for i in infos])
    planned = plan_units(infos, config, out)
    t_plan = time.perf_counter() - t0
    save_ledger(ledger, out / "ledger.json")
    t_save = time.perf_counter() - t0
    snapshot = (out / "ledger.json").stat().st_size if (out / "ledger.json").exists() else 0
    journal = out / "ledger.json.journal"
    return {
        "files": len(infos),
        "classification_tasks": len(batches),
        "unit_tasks": len(planned),
        "records_s": t_records,
        "plan_s": t_plan,
        "plan_and_save_s": t_save,
        "cpu_s": time.process_time() - c0,
        "driver_mib": (vm_kib("VmHWM") - base_kib) / 1024,
        "ledger_mb": (snapshot + (journal.stat().st_size if journal.exists() else 0)) / 1e6,
    }


def load_year(out: Path) -> dict[str, float]:
    """The year's ledger loaded back in this process (a next run's start)."""
    from cwproc.batch import load_ledger

    base_kib = vm_kib("VmRSS")
    t0 = time.perf_counter()
    ledger = load_ledger(out / "ledger.json")
    return {
        "files": len(ledger.files),
        "load_s": time.perf_counter() - t0,
        "load_peak_mib": (vm_kib("VmHWM") - base_kib) / 1024,
        "loaded_mib": (vm_kib("VmRSS") - base_kib) / 1024,
    }


def classify_per_file(folder: Path, n: int) -> float:
    """Step 2: CPU seconds per file of classify_batch on ``n`` files cut after 3 rays."""
    from cwproc.batch.worker import classify_batch, classify_file
    from cwproc.config import Config
    from cwproc.io.halo import write_hpl

    folder.mkdir(parents=True, exist_ok=True)
    start = np.datetime64("2024-06-01T00:00:00", "ns")
    full = day_spec.scan(start, 0)
    path = write_hpl(full, folder / "full.hpl")
    head = path.read_bytes()
    cut = head[: head.index(b"\n", len(head) // 60) + 1]  # header and the first rays
    path.unlink()
    paths = []
    for k in range(n):
        p = folder / file_name(150, k % FILES_PER_DAY).rsplit("/", 1)[1].replace(
            ".hpl", f"_{k}.hpl"
        )
        p.write_bytes(cut)
        paths.append(str(p))
    toml = Config().to_toml()
    classify_batch([(paths[0], "header")], classify_file, toml)  # imports out of the figure
    c0 = time.process_time()
    infos = classify_batch([(p, "header") for p in paths], classify_file, toml)
    cpu = time.process_time() - c0
    bad = [i.error for i in infos if i.status != "ok"]
    if bad:
        raise SystemExit(f"classification failed: {bad[0]}")
    return cpu / n


def month_counts(days: int, scans: int) -> list[int]:
    """Scans of each day of the month: ``scans``, ``2 * scans``, ``3 * scans`` in turn."""
    return [scans * (1 + d % 3) for d in range(days)]


def write_month(root: Path, counts: Sequence[int]) -> int:
    """Day ``d`` of June 2024 (and on) gets its first ``counts[d]`` scans; bytes written."""
    from cwproc.io.halo import write_hpl

    total = 0
    for d, count in enumerate(counts):
        day = np.datetime64("2024-06-01T00:00:00", "ns") + np.timedelta64(d, "D")
        folder = root / str(day)[:10].replace("-", "/")
        folder.mkdir(parents=True)
        for k in range(count):
            start = day + np.timedelta64(int(day_spec.PERIOD_S * 1e9) * k, "ns")
            stamp = np.datetime_as_string(start, unit="s").replace("-", "").replace(":", "")
            path = folder / f"VAD_999_{stamp[:8]}_{stamp[9:15]}.hpl"
            write_hpl(day_spec.scan(start, 1000 * d + k), path)
            total += path.stat().st_size
    return total


def process_month(archive: Path, out: Path, workers: int, dask: bool) -> tuple[float, object]:
    """One first run over the month: wall time (s) and its report."""
    from cwproc.batch import close_client, dask_client, local_pool, run_batch
    from cwproc.config import load_config

    config = load_config("streamline")
    client = None
    if workers:
        client = dask_client(workers=workers) if dask else local_pool(workers)
    try:
        t0 = time.perf_counter()
        report = run_batch(archive, out, config, client=client)
        wall = time.perf_counter() - t0
    finally:
        if client is not None:
            close_client(client)
    if not report.ok:
        raise SystemExit("\n".join(report.failure_lines()))
    return wall, report


def product_checksums(folder: Path) -> dict[str, str]:
    """``{product/variable: SHA-256}`` of every variable of every product in ``folder``.

    The checksum covers the variable's dimensions, dtype and values (NaN patterns
    included) and its attributes; the global attributes (creation dates, UUIDs, history)
    are not product data and are left out.
    """
    import hashlib

    from cwproc.io.netcdf import read_product

    sums = {}
    for path in sorted(folder.glob("*.nc")):
        ds = read_product(path)
        for name, var in sorted({**ds.coords, **ds.data_vars}.items()):
            digest = hashlib.sha256(repr((var.dims, str(var.dtype), var.shape)).encode())
            digest.update(np.ascontiguousarray(var.values).tobytes())
            digest.update(json.dumps(var.attrs, sort_keys=True, default=str).encode())
            sums[f"{path.name}/{name}"] = digest.hexdigest()
    return sums


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--days", type=int, default=30, help="days of the month (30)")
    parser.add_argument(
        "--scans", type=int, default=32, help="scans of the month's days: N, 2N, 3N in turn"
    )
    parser.add_argument("--header-files", type=int, default=2000)
    parser.add_argument("--no-dask", action="store_true", help="leave out the LocalCluster")
    parser.add_argument("--plan-only", action="store_true", help="only the year's planning")
    parser.add_argument("--plan-child", metavar="DIR", help=argparse.SUPPRESS)
    parser.add_argument("--load-child", metavar="DIR", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.plan_child or args.load_child:
        child = plan_year if args.plan_child else load_year
        print(json.dumps(child(Path(args.plan_child or args.load_child))))
        return
    work = Path(tempfile.mkdtemp(prefix="cwproc_year_"))
    try:
        run(args, work)
    finally:
        shutil.rmtree(work, ignore_errors=True)


def child(flag: str, folder: Path) -> dict[str, float]:
    """The figures of this script run as ``--plan-child``/``--load-child`` on ``folder``
    in a new process (its peak memory is the driver's)."""
    done = subprocess.run(
        [sys.executable, __file__, flag, str(folder)], capture_output=True, text=True, check=True
    )
    return json.loads(done.stdout.strip().splitlines()[-1])


def print_plan(work: Path) -> dict[str, float]:
    """Step 1 in a child process, then the ledger loaded back in another; printed."""
    (work / "plan").mkdir()
    plan = child("--plan-child", work / "plan")
    print(
        f"planning the year ({plan['files']:,} files, driver): "
        f"{plan['classification_tasks']} classification tasks + {plan['unit_tasks']} unit "
        f"tasks; records {plan['records_s']:.1f} s, planned at {plan['plan_s']:.1f} s, "
        f"ledger saved at {plan['plan_and_save_s']:.1f} s (CPU {plan['cpu_s']:.1f} s); "
        f"driver memory {plan['driver_mib']:.0f} MiB; ledger {plan['ledger_mb']:.0f} MB",
        flush=True,
    )
    load = child("--load-child", work / "plan")
    print(
        f"the year's ledger loaded by the next run: {load['load_s']:.1f} s, driver peak "
        f"{load['load_peak_mib']:.0f} MiB, {load['loaded_mib']:.0f} MiB once loaded",
        flush=True,
    )
    return plan


def run(args: argparse.Namespace, work: Path) -> None:
    plan = print_plan(work)
    if args.plan_only:
        return
    per_file = classify_per_file(work / "heads", args.header_files)
    classify_year = per_file * YEAR_FILES
    print(
        f"classification on the workers: {1e3 * per_file:.3f} ms CPU a file "
        f"({args.header_files} files cut after their first rays) -> {classify_year:.0f} "
        "CPU s for the year",
        flush=True,
    )
    counts = month_counts(args.days, args.scans)
    t0 = time.perf_counter()
    size = write_month(work / "archive", counts)
    print(
        f"month: {args.days} days of {args.scans}/{2 * args.scans}/{3 * args.scans} VADs "
        f"in turn, {sum(counts)} files, {size / 1e9:.2f} GB (written in "
        f"{time.perf_counter() - t0:.0f} s)",
        flush=True,
    )
    walls, reports = process_ways(work, args.no_dask)
    t_day, efficiency = year_day(reports["1 worker"], counts, walls)
    for cores in (2, 4, 8, 16, 64):
        free = plan["plan_and_save_s"] + (classify_year + DAYS * t_day) / cores
        year = plan["plan_and_save_s"] + classify_year / cores + DAYS * t_day / (cores * efficiency)
        print(
            f"the year on {cores:2d} cores: {year / 60:6.1f} min at the measured efficiency, "
            f"{free / 60:6.1f} min on free cores (efficiency 1)",
            flush=True,
        )
    added = (DAYS * t_day + classify_year) / 3600
    print(
        f"per added core: {1 / added * DAYS:.1f} days of the year an hour "
        f"({added:.2f} core-hours for the year's units and classification on free cores)"
    )


def process_ways(work: Path, no_dask: bool) -> tuple[dict[str, float], dict[str, object]]:
    """The month on 1 and 2 pool workers and a LocalCluster of 2, after an untimed serial
    run (imports, tables; the reference products). The LocalCluster comes last: a pool
    forked in a process that runs a LocalCluster hangs."""
    archive = work / "archive"
    wall, _ = process_month(archive, work / "serial", 0, False)
    print(f"month serial (untimed warm-up, the reference products): wall {wall:.1f} s")
    reference = product_checksums(work / "serial")
    ways = [("1 worker", 1, False), ("2 workers", 2, False)]
    if not no_dask:
        ways.append(("LocalCluster 2", 2, True))
    walls: dict[str, float] = {}
    reports: dict[str, object] = {}
    for label, workers, dask in ways:
        out = work / label.replace(" ", "_")
        wall, report = process_month(archive, out, workers, dask)
        walls[label], reports[label] = wall, report
        sums = product_checksums(out)
        print(
            f"month {label}: wall {wall:.1f} s, {len(report.processed)} units, "
            f"{len(sums)} product variables identical to serial: {sums == reference}",
            flush=True,
        )
        shutil.rmtree(out)
    return walls, reports


def year_day(report: object, counts: Sequence[int], walls: dict[str, float]) -> tuple[float, float]:
    """The time of a full day of 1920 files on one core from the month's units (least
    squares line of unit seconds against files: a cost per unit plus a cost per file),
    and the efficiency of 2 workers; printed."""
    by_day = {o.key: o.seconds for o in report.processed}
    keys = sorted(by_day)
    n = np.array(counts[: len(keys)], dtype=float)
    seconds = np.array([by_day[k] for k in keys])
    per_file, per_unit = np.polyfit(n, seconds, 1)
    t_day = per_unit + per_file * FILES_PER_DAY
    efficiency = walls["1 worker"] / walls["2 workers"] / 2
    print(
        f"a day of {FILES_PER_DAY} files: {t_day:.1f} s on one core "
        f"({per_file * 1e3:.2f} ms a file + {per_unit:.2f} s a unit, line through "
        f"{len(keys)} units); 2 workers / 1 worker: speed-up {2 * efficiency:.2f} "
        f"(efficiency {efficiency:.2f})",
        flush=True,
    )
    return t_day, efficiency


if __name__ == "__main__":
    main()
