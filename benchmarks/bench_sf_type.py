"""Speed of ``cwproc sf-type`` on a day of 10.7 Hz TOA5 against a bare pandas read (issue 15).

Writes one UTC day of synthetic 10.7 Hz sonic data (the virtual sonic,
:mod:`cwproc.sim.sonic`) as a Campbell TOA5 file (924,480 records, 62 MB), then prints,
in one run, for each interpreter given (``--python``; e.g. the project's venv, which
has the optional dask installed, and a plain ``pip install cwproc``):

1. ``pandas.read_csv`` of that file (the four header lines skipped) as a whole process;
2. ``cwproc sf-type FILE -o OUT`` as a whole process (start-up, imports, read, typing,
   writing the product and the tables);
3. their ratio, of wall times and of CPU times (user + system; the steadier figure on a
   shared machine), each the best of ``--repeat`` alternated runs (target: <= 2), and
   the ratio to the read run with OpenBLAS on one thread, as ``sf-type`` runs;
   every process runs outside the checkout, so that each interpreter runs its own
   ``cwproc`` (an interpreter whose ``cwproc`` is another commit compares commits),
   byte-compiled first as an install is (:func:`byte_compile`);
4. with ``--days N``: ``cwproc batch`` over N days (one file per day, the path a user
   runs for a month) serially, on a pool of one and of two workers, and the speed-up of
   two workers (target >= 1.8 on two free cores).

Run::

    python benchmarks/bench_sf_type.py                       # one day, this venv
    python benchmarks/bench_sf_type.py --python .venv/bin/python /tmp/plain/bin/python
    python benchmarks/bench_sf_type.py --days 30 --repeat 1  # and a month in parallel
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import host_scaling
import numpy as np
import pandas as pd

from cwproc.sim.sonic import iter_sonic_chunks

RATE_HZ = 10.7


def write_toa5_day(path: Path, day: int, seed: int = 0) -> None:
    """One UTC day of 10.7 Hz data in the layout of a CR3000 ``ts`` table."""
    start = np.datetime64("2014-06-01T00:00:00", "ns") + np.timedelta64(day, "D")
    with open(path, "w", newline="\n") as out:
        out.write(
            '"TOA5","6843","CR3000","6843","CR3000.Std.22","CPU:sim.CR3","24006","ts_Above"\n'
            '"TIMESTAMP","RECORD","Ux","Uy","Uz","Ts","diag_csat"\n'
            '"TS","RN","m/s","m/s","m/s","C","unitless"\n'
            '"","","Smp","Smp","Smp","Smp","Smp"\n'
        )
        record = 0
        for chunk in iter_sonic_chunks(hours=24.0, sf_type=2, seed=seed + day, start=str(start)):
            n = chunk.sizes["time"]
            times = pd.DatetimeIndex(chunk["time"].values).strftime("%Y-%m-%d %H:%M:%S.%f")
            frame = pd.DataFrame(
                {
                    "TIMESTAMP": '"' + times.str.rstrip("0").str.rstrip(".") + '"',
                    "RECORD": np.arange(record, record + n),
                    "Ux": chunk["u"].values.round(5),
                    "Uy": chunk["v"].values.round(5),
                    "Uz": chunk["w"].values.round(5),
                    "Ts": np.round(20.0 + chunk["temperature"].values * 0 + 0.1, 4)
                    if "temperature" in chunk
                    else 20.0,
                    "diag_csat": 0,
                }
            )
            frame.to_csv(out, header=False, index=False, quoting=3, lineterminator="\n")
            record += n


def run(cmd: list[str], env: dict | None = None) -> tuple[float, float]:
    """Wall time and CPU time (user + system, s) of one process.

    The process runs in the system's temporary folder: ``python -m cwproc`` started in a
    checkout would import that checkout's ``cwproc`` (the current folder comes first on
    ``sys.path``), not the one installed for the interpreter being timed.
    """
    t0 = time.perf_counter()
    proc = subprocess.Popen(
        cmd,
        env=env,
        cwd=tempfile.gettempdir(),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
    )
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    proc.returncode = os.waitstatus_to_exitcode(status)
    err = proc.stderr.read().decode() if proc.stderr else ""
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed ({proc.returncode}): {err[-2000:]}")
    return wall, usage.ru_utime + usage.ru_stime


def best(times: list[tuple[float, float]]) -> tuple[float, float]:
    """The fastest wall time and the smallest CPU time of repeated runs."""
    return min(t[0] for t in times), min(t[1] for t in times)


def byte_compile(python: str) -> None:
    """Byte-compile the ``cwproc`` of ``python``, as an install does.

    pandas, xarray and the rest come with their ``.pyc`` files; a source checkout
    installed in editable mode has none until a run writes them, and none is ever
    written where ``PYTHONDONTWRITEBYTECODE`` is set: each timed ``sf-type`` would then
    compile cwproc's modules from source (~40 ms), which no installed copy does.
    """
    where = subprocess.run(
        [python, "-c", "import cwproc, os; print(os.path.dirname(cwproc.__file__))"],
        capture_output=True,
        text=True,
        check=True,
        cwd=tempfile.gettempdir(),
    ).stdout.strip()
    subprocess.run([python, "-m", "compileall", "-q", where], check=True)


def compare_one_day(path: Path, out: Path, python: str, repeat: int) -> dict[str, float]:
    """Bare ``pandas.read_csv`` and ``cwproc sf-type`` of one file, alternated ``repeat``
    times (the machine is shared: each figure is the best of its runs).

    ``sf-type`` starts OpenBLAS with one thread (its idle threads spin for ~0.1 s of
    CPU); the read is also timed with ``OPENBLAS_NUM_THREADS=1``, so that the ratio
    is shown without that gain as well.
    """
    code = f"import pandas; pandas.read_csv({str(path)!r}, skiprows=[0, 2, 3])"
    one_thread = {**os.environ, "OPENBLAS_NUM_THREADS": "1"}
    reads, reads_1, types = [], [], []
    for _ in range(repeat):
        reads.append(run([python, "-c", code]))
        reads_1.append(run([python, "-c", code], env=one_thread))
        types.append(run([python, "-m", "cwproc", "sf-type", str(path), "-o", str(out), "-q"]))
    (rw, rc), (r1w, r1c), (sw, sc) = best(reads), best(reads_1), best(types)
    return {
        "read wall": rw,
        "read cpu": rc,
        "read1 wall": r1w,
        "read1 cpu": r1c,
        "sf wall": sw,
        "sf cpu": sc,
    }


def write_month(folder: Path, days: int) -> list[Path]:
    """``days`` (<= 30) consecutive UTC days of June 2014: day 1 simulated, the others
    the same samples with their date changed (one file per day, as a logger writes)."""
    folder.mkdir(parents=True, exist_ok=True)
    first = folder / "TOA5_6843.ts_Above_2014_06_01_0000.dat"
    write_toa5_day(first, 0)
    text = first.read_bytes()
    paths = [first]
    for day in range(2, days + 1):
        path = folder / f"TOA5_6843.ts_Above_2014_06_{day:02d}_0000.dat"
        path.write_bytes(text.replace(b'"2014-06-01 ', f'"2014-06-{day:02d} '.encode()))
        paths.append(path)
    return paths


def compare_month(folder: Path, out: Path, python: str) -> dict[str, tuple[float, float]]:
    """``cwproc batch`` of the month serially, on a pool of 1 and of 2 workers."""
    times = {}
    for label, extra in (("serial", []), ("1 worker", ["--workers", "1"]),
                         ("2 workers", ["--workers", "2"])):  # fmt: skip
        target = out / label.replace(" ", "_")
        cmd = [python, "-m", "cwproc", "batch", str(folder), str(target), "-q", *extra]
        times[label] = run(cmd)
    return times


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument(
        "--days",
        type=int,
        default=0,
        help="also time `cwproc batch` over this many days (<= 30), 1 and 2 workers",
    )
    parser.add_argument(
        "--python",
        nargs="+",
        default=[sys.executable],
        help="interpreters of the installs to time (e.g. one with and one without dask)",
    )
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        tmp_path = Path(tmp)
        path = tmp_path / "TOA5_6843.ts_Above_2014_06_01_0000.dat"
        write_toa5_day(path, 0)
        t0 = time.perf_counter()
        pd.read_csv(path, skiprows=[0, 2, 3])
        read_inproc = time.perf_counter() - t0
        print(f"one day, {path.stat().st_size / 1e6:.1f} MB, {RATE_HZ} Hz TOA5, "
              f"best of {args.repeat} alternated runs")  # fmt: skip
        print(f"  pandas.read_csv in-process {read_inproc:.2f} s")
        for python in args.python:
            has_dask = (
                subprocess.run(
                    [python, "-c", "import dask"], capture_output=True, cwd=tempfile.gettempdir()
                ).returncode
                == 0
            )
            byte_compile(python)
            f = compare_one_day(path, tmp_path / "out", python, args.repeat)
            print(f"  {python} ({'with' if has_dask else 'without'} dask installed)")
            print(f"    pandas.read_csv process  {f['read wall']:6.2f} s wall, "
                  f"{f['read cpu']:6.2f} s CPU")  # fmt: skip
            print(f"    cwproc sf-type process   {f['sf wall']:6.2f} s wall, "
                  f"{f['sf cpu']:6.2f} s CPU")  # fmt: skip
            print(f"    ratio sf-type / read_csv {f['sf wall'] / f['read wall']:6.2f} wall, "
                  f"{f['sf cpu'] / f['read cpu']:.2f} CPU (target <= 2)")  # fmt: skip
            print(f"    read_csv, 1 BLAS thread  {f['read1 wall']:6.2f} s wall, "
                  f"{f['read1 cpu']:6.2f} s CPU: ratio {f['sf wall'] / f['read1 wall']:.2f} "
                  f"wall, {f['sf cpu'] / f['read1 cpu']:.2f} CPU")  # fmt: skip
        if args.days:
            month = write_month(tmp_path / f"month_{args.days}", min(args.days, 30))
            t = compare_month(month[0].parent, tmp_path / "month_out", args.python[0])
            print(f"{len(month)} days ({len(month) * path.stat().st_size / 1e9:.1f} GB), "
                  f"cwproc batch, {args.python[0]}")  # fmt: skip
            for label, (wall, cpu) in t.items():
                print(f"  {label:<10} {wall:7.2f} s wall, {cpu:7.2f} s CPU")
            print(f"  speed-up 2 workers / 1 worker {t['1 worker'][0] / t['2 workers'][0]:.2f}, "
                  f"/ serial {t['serial'][0] / t['2 workers'][0]:.2f} (target >= 1.8)")  # fmt: skip
            print(f"  {host_scaling.describe('after the runs; what 2 workers can reach')}")


if __name__ == "__main__":
    main()
