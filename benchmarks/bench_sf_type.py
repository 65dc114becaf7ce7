"""Speed of ``cwproc sf-type`` on a day of 10.7 Hz TOA5 against a bare pandas read (issue 15).

Writes one UTC day of synthetic 10.7 Hz sonic data (the virtual sonic,
:mod:`cwproc.sim.sonic`) as a Campbell TOA5 file (924,480 records, about 80 MB), then
prints, in one run:

1. ``pandas.read_csv`` of that file (the four header lines skipped), in-process;
2. ``cwproc sf-type FILE -o OUT`` as a whole process (start-up, read, typing, writing);
3. their ratio (target: <= 2);
4. with ``--days N`` (N >= 2): N such days typed by ``cwproc sf-type`` on one core
   (``CWPROC_WORKERS=1``) and on two (``--workers 2``), and the speed-up (target >= 1.8).

Run::

    python benchmarks/bench_sf_type.py            # one day
    python benchmarks/bench_sf_type.py --days 4   # and the parallel speed-up
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

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


def run(cmd: list[str], env: dict | None = None) -> float:
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, capture_output=True, env=env)
    return time.perf_counter() - t0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--days", type=int, default=1)
    parser.add_argument("--repeat", type=int, default=2)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        tmp_path = Path(tmp)
        files = []
        for day in range(args.days):
            path = tmp_path / f"TOA5_6843.ts_Above_2014_06_{day + 1:02d}_0000.dat"
            write_toa5_day(path, day)
            files.append(path)
        size = files[0].stat().st_size / 1e6
        code = f"import pandas; pandas.read_csv({str(files[0])!r}, skiprows=[0, 2, 3])"
        read = min(run([sys.executable, "-c", code]) for _ in range(args.repeat))
        t0 = time.perf_counter()
        pd.read_csv(files[0], skiprows=[0, 2, 3])
        read_inproc = time.perf_counter() - t0
        sf = min(
            run(["cwproc", "sf-type", str(files[0]), "-o", str(tmp_path / "out"), "-q"])
            for _ in range(args.repeat)
        )
        print(f"one day, {size:.1f} MB, {RATE_HZ} Hz TOA5")
        print(f"  pandas.read_csv  {read_inproc:6.2f} s in-process, {read:6.2f} s process")
        print(f"  cwproc sf-type (process)    {sf:6.2f} s")
        print(f"  ratio sf-type / read_csv    {sf / read_inproc:6.2f} (in-process read), "
              f"{sf / read:.2f} (process)")  # fmt: skip
        if args.days >= 2:
            paths = [str(f) for f in files]
            env1 = dict(os.environ, CWPROC_WORKERS="1")
            one = run(["cwproc", "sf-type", *paths, "-o", str(tmp_path / "o1"), "-q"], env1)
            env2 = dict(os.environ, CWPROC_WORKERS="2")
            two = run(["cwproc", "sf-type", *paths, "-o", str(tmp_path / "o2"), "-q"], env2)
            print(f"{args.days} days: one core {one:.2f} s, two cores {two:.2f} s, "
                  f"speed-up {one / two:.2f}")  # fmt: skip


if __name__ == "__main__":
    main()
