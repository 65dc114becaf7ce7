"""A lidar-year through ``cwproc batch``: planning at full scale, processing a slice.

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
   (VmHWM above the imports), the ledger's size, the number of tasks.
2. **Classification on the workers**, measured on ``--header-files`` real files of the
   year's layout cut after their first ray lines (classification reads a ``.hpl`` file's
   header and first ray only): CPU per file of :func:`classify_batch`, scaled to the
   year.
3. **A slice processed**: two units of ``--slice-files`` files each (N and 3N scans of
   a day, so that the time of a full day of 1920 files is the line through both:
   a cost per unit plus a cost per file), serially, on a local pool of 1 and 2
   workers (``--workers``) and on a Dask LocalCluster of 2 (with ``--dask``); the
   products of every way are compared with the serial run's (identical, dates aside).

The year's wall time on k cores = planning + classification / k + 365 x (day) / (k x
efficiency), with the efficiency of 2 workers measured here (units are independent:
beyond 2, the same efficiency is assumed, the shared file system aside).

Run (small on a loaded machine; compare figures of one run only)::

    OMP_NUM_THREADS=1 python benchmarks/bench_archive_year.py [--slice-files 48] [--dask]
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
            record_file(ledger, info)
            infos.append(info)
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


def write_slice(root: Path, files: int) -> list[int]:
    """Two day units of ``files`` and ``3 * files`` scans (the day's first scans)."""
    from cwproc.io.halo import write_hpl

    counts = [files, 3 * files]
    for d, count in enumerate(counts):
        day = np.datetime64("2024-06-01T00:00:00", "ns") + np.timedelta64(d, "D")
        folder = root / str(day)[:10]
        folder.mkdir(parents=True)
        for k in range(count):
            start = day + np.timedelta64(int(day_spec.PERIOD_S * 1e9) * k, "ns")
            stamp = np.datetime_as_string(start, unit="s").replace("-", "").replace(":", "")
            write_hpl(day_spec.scan(start, k), folder / f"VAD_999_{stamp[:8]}_{stamp[9:15]}.hpl")
    return counts


def process_slice(archive: Path, out: Path, workers: int, dask: bool) -> tuple[float, object]:
    """One first run over the slice: wall time (s) and its report."""
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


def same_products(a: Path, b: Path) -> bool:
    """Every product of ``a`` identical to ``b``'s (creation dates and UUIDs aside)."""
    import xarray as xr

    from cwproc.io.netcdf import read_product

    skip = {
        "history",
        "date_created",
        "date_modified",
        "date_issued",
        "date_metadata_modified",
        "file_uuid",
    }
    names = sorted(p.name for p in a.glob("*.nc"))
    if not names or names != sorted(p.name for p in b.glob("*.nc")):
        return False
    for name in names:
        da, db = read_product(a / name), read_product(b / name)
        da.attrs = {k: v for k, v in da.attrs.items() if k not in skip}
        db.attrs = {k: v for k, v in db.attrs.items() if k not in skip}
        try:
            xr.testing.assert_identical(da, db)
        except AssertionError:
            return False
    return True


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--slice-files", type=int, default=48)
    parser.add_argument("--header-files", type=int, default=2000)
    parser.add_argument("--dask", action="store_true", help="also a Dask LocalCluster of 2")
    parser.add_argument("--plan-only", metavar="DIR", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.plan_only:
        print(json.dumps(plan_year(Path(args.plan_only))))
        return
    work = Path(tempfile.mkdtemp(prefix="cwproc_year_"))
    try:
        run(args, work)
    finally:
        shutil.rmtree(work, ignore_errors=True)


def run(args: argparse.Namespace, work: Path) -> None:
    (work / "plan").mkdir()
    child = subprocess.run(
        [sys.executable, __file__, "--plan-only", str(work / "plan")],
        capture_output=True,
        text=True,
        check=True,
    )
    plan = json.loads(child.stdout.strip().splitlines()[-1])
    print(
        f"planning the year ({plan['files']:,} files, driver): "
        f"{plan['classification_tasks']} classification tasks + {plan['unit_tasks']} unit "
        f"tasks; records {plan['records_s']:.1f} s, planned at {plan['plan_s']:.1f} s, "
        f"ledger saved at {plan['plan_and_save_s']:.1f} s (CPU {plan['cpu_s']:.1f} s); "
        f"driver memory {plan['driver_mib']:.0f} MiB; ledger {plan['ledger_mb']:.0f} MB",
        flush=True,
    )
    per_file = classify_per_file(work / "heads", args.header_files)
    classify_year = per_file * YEAR_FILES
    print(
        f"classification on the workers: {1e3 * per_file:.3f} ms CPU a file "
        f"({args.header_files} files cut after their first rays) -> {classify_year:.0f} "
        "CPU s for the year",
        flush=True,
    )
    counts = write_slice(work / "archive", args.slice_files)
    process_slice(work / "archive", work / "warm-up", 0, False)  # imports, tables: untimed
    ways = [("serial", 0, False), ("1 worker", 1, False), ("2 workers", 2, False)]
    if args.dask:
        ways.append(("Dask LocalCluster 2", 2, True))
    walls: dict[str, float] = {}
    reports = {}
    for label, workers, dask in ways:
        out = work / label.replace(" ", "_")
        wall, report = process_slice(work / "archive", out, workers, dask)
        walls[label], reports[label] = wall, report
        seconds = sorted(o.seconds for o in report.processed)
        same = (
            ""
            if label == "serial"
            else f", products identical: {same_products(work / 'serial', out)}"
        )
        print(
            f"slice ({'+'.join(map(str, counts))} files) {label}: wall {wall:.1f} s, "
            f"unit seconds {', '.join(f'{s:.1f}' for s in seconds)}{same}",
            flush=True,
        )
    units = sorted(reports["serial"].processed, key=lambda o: o.seconds)
    t_small, t_large = units[0].seconds, units[-1].seconds
    per_scan = (t_large - t_small) / (counts[1] - counts[0])
    t_day = t_small + per_scan * (FILES_PER_DAY - counts[0])
    efficiency = walls["1 worker"] / walls["2 workers"] / 2
    print(
        f"a day of {FILES_PER_DAY} files: {t_day:.1f} s on one core "
        f"({per_scan * 1e3:.1f} ms a file + {t_small - per_scan * counts[0]:.1f} s a unit); "
        f"2 workers / 1 worker: speed-up {2 * efficiency:.2f} (efficiency {efficiency:.2f})"
    )
    for cores in (2, 4, 8, 16, 64):
        free = plan["plan_and_save_s"] + (classify_year + DAYS * t_day) / cores
        year = plan["plan_and_save_s"] + classify_year / cores + DAYS * t_day / (cores * efficiency)
        print(
            f"the year on {cores:2d} cores: {year / 60:6.1f} min at the measured efficiency, "
            f"{free / 60:6.1f} min on free cores (efficiency 1)",
            flush=True,
        )
    added = DAYS * t_day / 3600
    print(
        f"per added core: {1 / added * DAYS:.1f} days of the year an hour "
        f"({added:.1f} core-hours for the year's units on free cores)"
    )


if __name__ == "__main__":
    main()
