"""Peak memory of ``cwproc retrieve`` against the number of product units (issue 17.8).

Writes N site-days of the shipped sample scans (simulated Stream Line VAD files, two
per day, shifted by whole days) and runs ``cwproc retrieve`` on them in a child process
for N = 1, 8, 32 (and more with ``--days``), printing the child's peak resident memory
(``ru_maxrss``) and the input size. ``retrieve`` keeps at most
``cwproc.pipeline.retrieve.RETRIEVE_MEMORY_BYTES`` of inputs between reading and
processing and reads the rest again unit by unit, so the peak stays flat once the
inputs exceed that budget; ``--budget-mib`` lowers it to show the flat regime on a small archive.
The child calls the library (``retrieve_files``) with the allocator tuned as the
``cwproc retrieve`` program tunes it (``cwproc.memory.tune_allocator``; the library
alone leaves the process's allocator as it is).

Run::

    python benchmarks/bench_retrieve_memory.py
    python benchmarks/bench_retrieve_memory.py --days 1 8 32 --budget-mib 16
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

CHILD = """
import resource, sys
from pathlib import Path
from cwproc import memory
memory.tune_allocator()  # as the cwproc program does (cwproc.cli._group)
from cwproc.pipeline import retrieve
from cwproc.config import load_config
retrieve.RETRIEVE_MEMORY_BYTES = int(sys.argv[3])
files = sorted(Path(sys.argv[1]).rglob("*.hpl"))
config = load_config("streamline")
report = retrieve.retrieve_files(files, sys.argv[2], config)
assert report.ok, report.failures
print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)
"""


def write_days(root: Path, days: int) -> int:
    from cwproc.io.halo import read_hpl, write_hpl

    sample = Path(__file__).resolve().parents[1] / "sample_data" / "streamline"
    n = 0
    for path in sorted(sample.glob("*.hpl")):
        ds = read_hpl(path)
        for d in range(days):
            shifted = ds.assign_coords(time=ds["time"] + np.timedelta64(d, "D"))
            name = path.name.replace("20240601", f"202406{d + 1:02d}" if d < 29 else "20240601")
            folder = root / f"day{d:03d}"
            folder.mkdir(parents=True, exist_ok=True)
            write_hpl(shifted, folder / name)
            n += 1
    return n


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--days", type=int, nargs="+", default=[1, 8, 32])
    parser.add_argument("--budget-mib", type=float, default=16.0)
    args = parser.parse_args()
    budget = int(args.budget_mib * 2**20)
    print(f"retrieve input budget {args.budget_mib:g} MiB")
    print(f"{'units':>6s} {'files':>6s} {'input MiB':>10s} {'peak RSS MiB':>13s}")
    for days in args.days:
        with tempfile.TemporaryDirectory() as tmp:
            root = Path(tmp) / "in"
            n = write_days(root, days)
            size = sum(p.stat().st_size for p in root.rglob("*.hpl")) / 2**20
            out = subprocess.run(
                [sys.executable, "-c", CHILD, str(root), str(Path(tmp) / "out"), str(budget)],
                check=True,
                capture_output=True,
                text=True,
            )
            peak = float(out.stdout.strip().splitlines()[-1])
            print(f"{days:6d} {n:6d} {size:10.1f} {peak:13.0f}", flush=True)


if __name__ == "__main__":
    main()
