"""Start-up cost of the command line (issue 14: --version/--help < 0.3 s, main job's
fixed cost < 1 s).

    python benchmarks/bench_startup.py

prints, for ``cwproc --version``, ``cwproc --help`` and ``cwproc plot --help``, the
median wall time of 5 runs, and for the README main job (``cwproc retrieve
sample_data/ -c sample_data/site.toml -o OUT``) its wall time and its fixed cost: the
time spent importing modules, from ``python -X importtime`` (sum of the top-level
imports), which is what every run pays whatever the data.
"""

from __future__ import annotations

import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CLI = [sys.executable, "-m", "cwproc"]


def wall(args: list[str], runs: int = 5) -> float:
    """Median wall time (s) of ``args`` over ``runs`` runs."""
    times = []
    for _ in range(runs):
        t0 = time.perf_counter()
        subprocess.run(args, check=True, capture_output=True, cwd=ROOT)
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def import_seconds(args: list[str]) -> tuple[float, float, list[tuple[float, str]]]:
    """(wall time, total top-level import time, the 5 costliest top-level imports)."""
    t0 = time.perf_counter()
    res = subprocess.run(
        [sys.executable, "-X", "importtime", *args], capture_output=True, text=True, cwd=ROOT
    )
    elapsed = time.perf_counter() - t0
    if res.returncode != 0:
        raise SystemExit(res.stderr[-2000:])
    top = []
    for line in res.stderr.splitlines():
        if not line.startswith("import time:") or line.count("|") != 2:
            continue
        _, cumulative, name = line.split(":", 1)[1].split("|")
        # top-level entries of the importtime tree are indented by exactly one space
        if cumulative.strip().isdigit() and name.startswith(" ") and name[1] != " ":
            top.append((int(cumulative) / 1e6, name.strip()))
    return elapsed, sum(s for s, _ in top), sorted(top, reverse=True)[:5]


def main() -> int:
    print(f"{'command':<40} {'median wall (s)':>16}")
    for args in (["--version"], ["--help"], ["plot", "--help"], ["retrieve", "--help"]):
        print(f"{'cwproc ' + ' '.join(args):<40} {wall([*CLI, *args]):16.3f}")
    with tempfile.TemporaryDirectory() as tmp:
        job = [
            "-m",
            "cwproc",
            "retrieve",
            "sample_data/",
            "-c",
            "sample_data/site.toml",
            "-o",
            str(Path(tmp) / "out"),
        ]
        wall([sys.executable, *job], runs=1)  # warm the file-system caches
        elapsed, imports, worst = import_seconds(job)
    print(f"\nREADME main job: wall {elapsed:.2f} s, of which imports (fixed cost) {imports:.2f} s")
    for seconds, name in worst:
        print(f"  {name:<30} {seconds:6.3f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
