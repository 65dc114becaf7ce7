"""Benchmark: the virtual instrument's four cases of issue 30 (item 3), as a user runs them.

1. a Stream Line day: ``cwproc simulate lidar --hours 24 --gates 100 --scan-period 45
   --scans-per-file 1`` (1920 VADs of 180 rays, one ``.hpl`` file each; target < 3 min);
2. the cw lidar of Banakh et al. (1999), 3 minutes of data (``--instrument cw --hours
   0.05``, 26 scans at six heights);
3. ZephIR 300, half an hour (``--instrument zephir --hours 0.5``, 1800 scans);
4. ``cwproc simulate montecarlo`` with its defaults (1000 realisations, ``--no-png``).

Each runs as ``python -m cwproc ... -q`` in a child process with an empty cache
(``XDG_CACHE_HOME`` a fresh temporary folder) and output in a temporary folder; the
script prints the wall time and the CPU time (user + system of the child, all its
threads) of each. ``--checkout DIR`` runs the cases with another checkout of cwproc
(through ``PYTHONPATH``, e.g. the branch start) for a before/after on one machine; a case
whose options that checkout lacks is skipped with a note. ``--hours`` scales the Stream
Line day down for a quick run (the figure printed is then for that many hours).

Run::

    python benchmarks/bench_simulate.py [--hours 24] [--cases day cw zephir montecarlo]
        [--checkout DIR]
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

#: the issue's targets (s of wall time on 2 idle cores)
TARGETS = {"day": "< 180 s (24 h)", "cw": "10x faster", "zephir": "10x faster",
           "montecarlo": "about 60 s (README)"}  # fmt: skip


def case_args(name: str, hours: float, out: Path) -> list[str]:
    """The ``cwproc`` command line of a case."""
    if name == "day":
        return ["simulate", "lidar", "-o", str(out), "--hours", str(hours), "--gates", "100",
                "--scan-period", "45", "--scans-per-file", "1"]  # fmt: skip
    if name == "cw":
        return ["simulate", "lidar", "-o", str(out), "--instrument", "cw", "--hours", "0.05"]
    if name == "zephir":
        return ["simulate", "lidar", "-o", str(out), "--instrument", "zephir", "--hours", "0.5"]
    if name == "montecarlo":
        return ["simulate", "montecarlo", "-o", str(out), "--no-png"]
    raise ValueError(name)


def supports(checkout: Path, args: list[str]) -> bool:
    """Whether the checkout's ``cwproc`` knows every option of ``args`` (``--help``)."""
    command = args[:2]
    env = {**os.environ, "PYTHONPATH": str(checkout)}
    text = subprocess.run(
        [sys.executable, "-m", "cwproc", *command, "--help"],
        capture_output=True, text=True, env=env, check=False, cwd=checkout,
    ).stdout  # fmt: skip
    return all(f"{a} " in text or f"{a}," in text for a in args if a.startswith("-"))


def run_case(checkout: Path, args: list[str]) -> tuple[float, float, int]:
    """Wall and CPU seconds of ``python -m cwproc ARGS -q`` and the files it wrote."""
    with tempfile.TemporaryDirectory() as cache:
        env = {**os.environ, "PYTHONPATH": str(checkout), "XDG_CACHE_HOME": cache}
        quiet = ["-q"] if supports(checkout, [*args[:2], "-q"]) else []
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        start = time.perf_counter()
        proc = subprocess.run(  # in the checkout: "-m" puts the working folder first
            [sys.executable, "-m", "cwproc", *args, *quiet],
            capture_output=True, text=True, env=env, check=False, cwd=checkout,
        )  # fmt: skip
        wall = time.perf_counter() - start
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(args)} failed:\n{proc.stderr}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu, proc.stdout.count("wrote ")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--hours", type=float, default=24.0, help="Stream Line day (h)")
    parser.add_argument("--cases", nargs="+", default=list(TARGETS), choices=list(TARGETS))
    parser.add_argument("--checkout", type=Path, default=ROOT, help="cwproc checkout to run")
    args = parser.parse_args()
    print(f"cwproc of {args.checkout}; load average {os.getloadavg()[0]:.1f}")
    for name in args.cases:
        with tempfile.TemporaryDirectory() as out:
            cmd = case_args(name, args.hours, Path(out))
            if not supports(args.checkout, cmd):
                print(f"{name:>10}: skipped (this checkout lacks an option of: {' '.join(cmd)})")
                continue
            wall, cpu, files = run_case(args.checkout, cmd)
        label = f"{args.hours:g} h " if name == "day" else ""
        print(
            f"{name:>10}: {wall:7.1f} s wall, {cpu:7.1f} s CPU, {files} files written "
            f"{label}(target {TARGETS[name]}): cwproc {' '.join(cmd[:2])} {' '.join(cmd[4:])}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
