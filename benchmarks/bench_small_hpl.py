"""Small ``.hpl`` files (10-170 kB: short stares, step-stare VADs) read by cwproc and doppy.

Run (doppy in a separate venv that sees cwproc; it is not a cwproc dependency)::

    OMP_NUM_THREADS=1 PYTHONPATH=. /work/wt/venv35/bin/python benchmarks/bench_small_hpl.py

A synthetic day of one instrument (100 gates), written with
:func:`cwproc.io.halo.write_hpl` into a temporary folder: short stares of 3-5 rays
(10-18 kB) every other file, step-stare VADs of 12-48 rays (40-170 kB) between them
(``--files`` in all). In the same run, best of ``--repeat`` CPU times
(``time.process_time``; doppy's Rust code runs in-process too):

1. per file: ``cwproc.io.halo.read_hpl`` of each file against doppy's
   ``HaloHpl.from_src``, by size class and over the day;
2. the day into one dataset: ``cwproc.io.halo_files.read_hpl_files`` (what a streamed
   unit reads, chunk by chunk: ``read_hpl_run``) against doppy's ``from_srcs`` +
   (without ``merge``, which refuses files of different ray counts) and against
   ``from_src`` of each file.

Target (issue 35.2): cwproc at least 1.2 times doppy's speed on the day (ratio
doppy time / cwproc time).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_read_hpl import synthetic_vad

from cwproc.io.halo import read_hpl, write_hpl
from cwproc.io.halo_files import read_hpl_files

#: gates of every file of the day (one instrument setting)
N_GATES = 100


def small_file(start: np.datetime64, k: int) -> object:
    """File ``k`` of the day: a short stare (even ``k``) or a step-stare VAD (odd)."""
    ds = synthetic_vad(start, seed=k, n_gates=N_GATES)
    n_rays = 3 + k % 3 if k % 2 == 0 else 12 + (k * 7) % 37
    ds = ds.isel(ray=np.arange(n_rays) % ds.sizes["ray"])
    t = start + (np.arange(n_rays) * 2_000_000_000).astype("timedelta64[ns]")
    return ds.assign_coords(time=("ray", t))


def write_day(folder: Path, n_files: int) -> list[Path]:
    """``n_files`` small files spread over one day."""
    day = np.datetime64("2024-06-01T00:00:00", "ns")
    paths = []
    for k in range(n_files):
        start = day + np.timedelta64(int(86_000 / n_files * k), "s")
        stamp = str(start.astype("datetime64[s]")).replace("-", "").replace(":", "")
        kind = "Stare" if k % 2 == 0 else "VAD"
        name = f"{kind}_999_{stamp[:8]}_{stamp[9:15]}.hpl"
        paths.append(write_hpl(small_file(start, k), folder / name))
    return paths


def best_cpu(func: Callable[[], object], repeat: int) -> float:
    """Shortest CPU time (s) of ``repeat`` calls."""
    best = float("inf")
    for _ in range(repeat):
        c0 = time.process_time()
        func()
        best = min(best, time.process_time() - c0)
    return best


def line(label: str, paths: list[Path], t_cwproc: float, t_doppy: float) -> str:
    mb = sum(p.stat().st_size for p in paths) / 1e6
    return (
        f"{label:<44} {len(paths):4d} files {mb:6.2f} MB  cwproc {mb / t_cwproc:6.1f} MB/s "
        f"({1e3 * t_cwproc / len(paths):.3f} ms/file)  doppy {mb / t_doppy:6.1f} MB/s  "
        f"cwproc/doppy {t_doppy / t_cwproc:4.2f}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--files", type=int, default=240)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    try:
        import doppy
        from doppy.raw import HaloHpl
    except ImportError:
        sys.exit("doppy is not installed: pip install doppy (in a separate venv)")
    with tempfile.TemporaryDirectory() as tmp:
        paths = write_day(Path(tmp), args.files)
        sizes = np.array([p.stat().st_size for p in paths])
        print(
            f"doppy {doppy.__version__}; {len(paths)} files of {sizes.min() / 1e3:.0f}-"
            f"{sizes.max() / 1e3:.0f} kB, {N_GATES} gates; best of {args.repeat} (CPU)"
        )
        read_hpl(paths[0]), HaloHpl.from_src(str(paths[0]))  # imports out of the figures
        for label, chosen in (
            (
                "per file, stares 10-18 kB",
                [p for p, s in zip(paths, sizes, strict=True) if s < 20e3],
            ),
            (
                "per file, VADs 40-170 kB",
                [p for p, s in zip(paths, sizes, strict=True) if s >= 20e3],
            ),
            ("per file, the whole day", paths),
        ):
            tc = best_cpu(lambda c=chosen: [read_hpl(p) for p in c], args.repeat)
            td = best_cpu(lambda c=chosen: [HaloHpl.from_src(str(p)) for p in c], args.repeat)
            print(line(label, chosen, tc, td), flush=True)
        tc = best_cpu(lambda: read_hpl_files(paths), args.repeat)
        # doppy's merge refuses files of different ray counts: its reads alone
        td = best_cpu(lambda: HaloHpl.from_srcs([str(p) for p in paths]), args.repeat)
        print(line("the day in one dataset | from_srcs", paths, tc, td), flush=True)
        td1 = best_cpu(lambda: [HaloHpl.from_src(str(p)) for p in paths], args.repeat)
        print(line("the day in one dataset | from_src each", paths, tc, td1), flush=True)


if __name__ == "__main__":
    main()
