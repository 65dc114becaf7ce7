"""Throughput of ``cwproc batch`` on a synthetic archive, serial and on Dask workers.

The archive: ``--days`` site-days of simulated Stream Line VAD scans (the sample-data
simulator, :func:`cwproc.sim.sample_data.simulate_streamline`, shifted by whole days;
two ``.hpl`` files per day) plus, when the Meteo-2 reader exists, ``--sonic-hours`` of
simulated sonic data per day (one file per day). Each configuration processes the
archive into a fresh output directory; then the same archive is run again to time a
run with nothing to do (ledger check only).

Run::

    python benchmarks/bench_batch.py                      # 30 days, 1 and 2 workers
    python benchmarks/bench_batch.py --days 10 --wind-only

Printed figures: wall time and units per second of the serial run and of local process
pools of 1 and 2 workers (``--workers``; with ``--dask`` also Dask LocalClusters of
the same sizes), the time and bytes read per file of classifying the ``.hpl`` and the
other files (in this process, as a first run does), the wall and CPU time of each
first run (CPU of the ended pool processes included) and, for the serial run, the bytes
read per input file (Linux ``rchar``; with ``--warm-up`` free of the first run's
imports), the speed-up of 2 workers over 1 and over serial (issue 15: >= 1.7), the peak
resident memory of each worker process (MiB, ``ru_maxrss``), and the time of a
run that finds everything up to date. Target: speed-up >= 1.7 on 2 free cores; peak
memory per worker < 1 GiB for a site-day of scans.
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib.util
import resource
import shutil
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

import host_scaling
import numpy as np

from cwproc.batch import (
    BatchReport,
    classify_file,
    close_client,
    dask_client,
    local_pool,
    run_batch,
)
from cwproc.config import Config, TurbulenceConfig


def write_scan_days(root: Path, days: int) -> int:
    """``days`` site-days of simulated Stream Line files under ``root/<day>/``."""
    from cwproc.io.halo import write_hpl
    from cwproc.sim.sample_data import (
        StreamLineSpec,
        hpl_file_name,
        simulate_streamline,
        split_files,
    )

    spec = StreamLineSpec()
    base = simulate_streamline(spec)
    n = 0
    for d in range(days):
        shifted = base.assign_coords(time=base["time"] + np.timedelta64(d, "D"))
        for part in split_files(shifted, spec.scans_per_file):
            folder = root / "lidar" / np.datetime_as_string(part["time"].values[0], unit="D")
            folder.mkdir(parents=True, exist_ok=True)
            write_hpl(part, folder / hpl_file_name(part))
            n += 1
    return n


def write_sonic_days(root: Path, days: int, hours: float) -> int:
    """One simulated Meteo-2 file of ``hours`` per day (0 when the reader is missing)."""
    if hours <= 0 or importlib.util.find_spec("cwproc.io.meteo2") is None:
        return 0
    from cwproc.sim.sonic import write_simulation

    n = 0
    for d in range(days):
        day = np.datetime64("2024-06-01") + np.timedelta64(d, "D")
        files, truth = write_simulation(
            root / "sonic", hours=hours, seed=d, start=f"{day}T12:00:00"
        )
        truth.unlink()
        n += len(files)
    return n


def memory_per_worker(report: BatchReport) -> dict[tuple[str, int], float]:
    """Peak RSS (MiB) of each process that ran units."""
    peaks: dict[tuple[str, int], float] = defaultdict(float)
    for o in report.processed:
        peaks[(o.host, o.pid)] = max(peaks[(o.host, o.pid)], o.peak_rss_mib)
    return dict(peaks)


def timed_run(
    archive: Path, out: Path, config: Config, workers: int | None, dask: bool = False
) -> BatchReport:
    """One batch run; ``workers``: a local process pool (``--workers``) or, with ``dask``,
    a Dask LocalCluster of that many single-threaded processes (for comparison)."""
    client = None
    if workers:
        client = dask_client(workers=workers) if dask else local_pool(workers)
    try:
        return run_batch(archive, out, config, client=client)
    finally:
        if client is not None:
            close_client(client)


def bytes_read() -> int | None:
    """Bytes this process has read so far (Linux ``rchar`` of ``/proc/self/io``: every
    ``read`` call, page cache included), None where ``/proc`` does not say."""
    try:
        with open("/proc/self/io", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("rchar:"):
                    return int(line.split()[1])
    except (OSError, ValueError, IndexError):
        pass
    return None


def cpu_seconds() -> float:
    """CPU time (user + system, s) of this process and of its ended child processes."""
    own = resource.getrusage(resource.RUSAGE_SELF)
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


def classification_figures(files: list[Path], config: Config) -> str:
    """Wall and CPU time (s) and bytes read per file (KiB) of classifying ``files``
    in this process, as a first run does before planning (:func:`classify_file`)."""
    toml = config.to_toml()
    classify_file(str(files[0]), toml)  # imports and lazy loads out of the figures
    read0, cpu0, wall0 = bytes_read(), cpu_seconds(), time.perf_counter()
    for path in files:
        classify_file(str(path), toml)
    wall, cpu = time.perf_counter() - wall0, cpu_seconds() - cpu0
    line = f"classify {len(files)} files: wall {wall:.3f} s, CPU {cpu:.3f} s"
    read1 = bytes_read()
    if read0 is not None and read1 is not None:
        line += f", read {(read1 - read0) / len(files) / 2**10:.0f} KiB per file"
    return line


def unit_seconds_by_kind(report: BatchReport) -> dict[str, float]:
    """Mean processing time of a unit (s, as measured on the worker) per unit prefix."""
    times: dict[str, list[float]] = defaultdict(list)
    for o in report.processed:
        times[o.key.split("_")[0]].append(o.seconds)
    return {kind: float(np.mean(t)) for kind, t in sorted(times.items())}


def describe(label: str, report: BatchReport) -> str:
    n = len(report.processed)
    peaks = memory_per_worker(report)
    mem = ", ".join(f"{v:.0f}" for v in sorted(peaks.values()))
    per_unit = ", ".join(f"{k} {v:.2f} s" for k, v in unit_seconds_by_kind(report).items())
    return (
        f"{label:<10} {report.seconds:8.2f} s  {n / report.seconds:6.2f} units/s  "
        f"{len(report.succeeded)} ok, {len(report.failed)} failed  "
        f"mean per unit: {per_unit}  peak RSS per process (MiB): {mem}"
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--days", type=int, default=30, help="site-days of scans (30)")
    parser.add_argument("--sonic-hours", type=float, default=0.5, help="sonic hours per day")
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    parser.add_argument(
        "--wind-only", action="store_true", help="turbulence stages off (wind product only)"
    )
    parser.add_argument("--workdir", type=Path, default=None, help="keep the files here")
    parser.add_argument(
        "--dask", action="store_true", help="also time Dask LocalClusters of the same sizes"
    )
    parser.add_argument(
        "--warm-up",
        action="store_true",
        help="run the archive once serially, untimed, first (imports and lazy loads "
        "out of the figures, so the bytes read per input count the run's own reads)",
    )
    args = parser.parse_args(argv)

    work = args.workdir or Path(tempfile.mkdtemp(prefix="cwproc-bench-batch-"))
    archive = work / "archive"
    if archive.exists():
        shutil.rmtree(archive)
    t0 = time.perf_counter()
    n_scan = write_scan_days(archive, args.days)
    n_sonic = write_sonic_days(archive, args.days, args.sonic_hours)
    size_mib = sum(p.stat().st_size for p in archive.rglob("*") if p.is_file()) / 2**20
    print(
        f"archive: {args.days} site-days, {n_scan} .hpl + {n_sonic} sonic files, "
        f"{size_mib:.1f} MiB, {size_mib * 2**10 / (n_scan + n_sonic):.0f} KiB per file "
        f"(made in {time.perf_counter() - t0:.1f} s)"
    )
    config = Config()
    if args.wind_only:
        config = dataclasses.replace(config, turbulence=TurbulenceConfig(enabled=False))

    times: dict[str, float] = {}
    runs = [("serial", None, False)] + [
        (f"{w} worker{'s' * (w > 1)}", w, False) for w in args.workers
    ]
    if args.dask:
        runs += [(f"dask {w}", w, True) for w in args.workers]
    files = sorted(p for p in archive.rglob("*") if p.is_file())
    n_files = len(files)
    hpl = [p for p in files if p.suffix == ".hpl"]
    for label, chosen in ((".hpl", hpl), ("other", [p for p in files if p not in hpl])):
        if chosen:
            print(f"{label:<10} {classification_figures(chosen, config)}")
    if args.warm_up:
        run_batch(archive, work / "out_warm_up", config)
    for label, workers, dask in runs:
        out = work / f"out_{label.replace(' ', '_')}"
        shutil.rmtree(out, ignore_errors=True)
        read0, cpu0, wall0 = bytes_read(), cpu_seconds(), time.perf_counter()
        report = timed_run(archive, out, config, workers, dask)
        wall, cpu = time.perf_counter() - wall0, cpu_seconds() - cpu0
        times[label] = report.seconds
        print(describe(label, report))
        print(f"{'':<10} first run, whole call: wall {wall:.2f} s, CPU {cpu:.2f} s", end="")
        read1 = bytes_read()
        if workers is None and read0 is not None and read1 is not None:
            # in-process run: every byte read of inputs, ledger and products
            per_input = (read1 - read0) / n_files / 2**10
            print(f", read {per_input:.0f} KiB per input file", end="")
        print()
        for line in report.failure_lines()[:3]:
            print(f"    failure: {line}")
    if 1 in args.workers and 2 in args.workers:
        print(f"speed-up 2 workers / 1 worker: {times['1 worker'] / times['2 workers']:.2f}")
        print(host_scaling.describe("after the runs; what 2 workers can reach"))
    if 2 in args.workers:
        print(f"speed-up 2 workers / serial: {times['serial'] / times['2 workers']:.2f}")
    if args.dask and 2 in args.workers:
        print(f"speed-up dask 2 / serial: {times['serial'] / times['dask 2']:.2f}")
    again = run_batch(archive, work / "out_serial", config)
    print(
        f"rerun with nothing to do: {again.seconds:.2f} s "
        f"({again.units_up_to_date} units up to date, {len(again.processed)} processed)"
    )
    if args.workdir is None:
        shutil.rmtree(work)
    return 0


if __name__ == "__main__":
    sys.exit(main())
