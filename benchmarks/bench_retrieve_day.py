"""``cwproc retrieve`` of a day of Stream Line scans: peak memory and time against reading.

Issue 15.3: a simulated 24-h day of 180-ray VAD scans every 45 s with 100 gates (1920
scans, one ``.hpl`` file per scan as the Stream Line writes them) is

1. read file by file with :func:`cwproc.io.halo.read_hpl` in a child process (imports
   included): the time to read the files, at its fastest. Dask is kept out of the
   process, as ``cwproc`` keeps it out of every command but ``batch``
   (``cwproc.cli._group.keep_dask_out``: xarray would import it, 0.5 s, to ask whether
   the arrays are dask's), and freed arrays are reused
   (``cwproc.memory.keep_freed_arrays``, as the retrieve's chunks have them): with
   glibc's defaults each file's arrays were mapped and zeroed afresh, 800 000 page
   faults and 1.5 s of system time for the day;
2. retrieved with ``python -m cwproc retrieve DAY -o OUT -q -c streamline`` in a child
   process, the command a user runs (wind and turbulence products of the day);

and the script prints both times (wall and CPU, best of ``--repeat``), their ratio
(target <= 1.5; also the ratio of each repeat, whose retrieve runs right after its
read, and their median: the machine is shared, and a neighbour's load moves both
bests) and the peak resident memory of the retrieve process (``ru_maxrss`` of the
child, all its threads; target < 300 MiB). The retrieve runs with its reading thread
(the next chunk read, parsed and checksummed beside the numerical work on the one
before; ``cwproc.pipeline.stream.UnitChunks``, the allocator tuned for the chunks by
the program, ``cwproc.memory``); ``--serial`` also runs it in one thread
(``CWPROC_READ_AHEAD=0``), side by side.
``--baseline CHECKOUT`` also runs the retrieve of another checkout of cwproc (e.g.
main's, imported through ``PYTHONPATH``, with this interpreter), each repeat right
after this one, prints this checkout's times and peak as ratios to it (the machine is
shared, so only figures of one run, back to back, compare) and compares the products
of every variant with the baseline's, variable by variable: bit for bit, else to
round-off (:data:`ROUND_OFF`), integers and flags always bit for bit (attributes that
name the run, such as its date, aside).

Run::

    python benchmarks/bench_retrieve_day.py [--repeat 2] [--scans 1920] [--day-dir DIR]
        [--serial] [--baseline CHECKOUT]

Both checkouts are byte-compiled first (:func:`byte_compile`). ``--day-dir`` keeps
the day's files in ``DIR`` (written there when it holds no ``.hpl``
file, reused as they are otherwise), so that repeated runs do not write them again.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import netCDF4
import numpy as np
import xarray as xr

from cwproc.io.halo import write_hpl

#: the issue's day: 180-ray scans every 45 s, 100 gates of 30 m
RAYS, PERIOD_S, GATES, GATE_M, ELEVATION = 180, 45.0, 100, 30.0, 75.0

_READ = """
import sys
sys.modules["dask"] = None  # as cwproc keeps it out (cwproc.cli._group.keep_dask_out)
from cwproc.memory import keep_freed_arrays
keep_freed_arrays()  # freed arrays reused, as cwproc's chunks have them (memory.phase)
from pathlib import Path
from cwproc.io.halo import read_hpl
for p in sorted(Path(sys.argv[1]).glob("*.hpl")):
    read_hpl(p)
"""


def scan(start: np.datetime64, seed: int) -> xr.Dataset:
    """One 180-ray VAD of a sheared wind with noise (0.25 s per ray)."""
    rng = np.random.default_rng(seed)
    az = np.arange(RAYS) * (360.0 / RAYS)
    rng_m = (np.arange(GATES) + 0.5) * GATE_M
    height = rng_m * np.sin(np.radians(ELEVATION))
    u, v = 5.0 + 0.004 * height, -2.0 + 0.002 * height
    cos_el = np.cos(np.radians(ELEVATION))
    vr = cos_el * (np.outer(np.sin(np.radians(az)), u) + np.outer(np.cos(np.radians(az)), v))
    snr = 0.5 * np.exp(-rng_m / 1500.0)[None, :] * rng.uniform(0.8, 1.2, (RAYS, GATES))
    vr = vr + rng.normal(0, 0.1, vr.shape) / np.sqrt(snr + 0.01)
    dt = PERIOD_S / RAYS * 1e9
    times = start + (np.arange(RAYS) * dt).astype("timedelta64[ns]")
    return xr.Dataset(
        {
            "radial_velocity": (("ray", "range"), np.round(vr, 4)),
            "snr": (("ray", "range"), np.round(snr, 6)),
            "beta": (("ray", "range"), 1e-6 * snr),
            "pitch": ("ray", np.full(RAYS, -0.1)),
            "roll": ("ray", np.full(RAYS, 0.2)),
        },
        coords={
            "time": ("ray", times),
            "azimuth": ("ray", az),
            "elevation": ("ray", np.full(RAYS, ELEVATION)),
            "range": ("range", rng_m),
        },
        attrs={
            "system_id": "999",
            "scan_type": "VAD",
            "gate_length_m": GATE_M,
            "points_per_gate": 10,
            "pulses_per_ray": 10000,
            "velocity_resolution_m_s": 0.0382,
        },
    )


def write_day(folder: Path, n_scans: int) -> int:
    """``n_scans`` scans from 2024-06-01 00:00 UTC, one file each; total bytes."""
    day = np.datetime64("2024-06-01T00:00:00", "ns")
    total = 0
    for k in range(n_scans):
        start = day + np.timedelta64(int(PERIOD_S * 1e9) * k, "ns")
        stamp = np.datetime_as_string(start, unit="s").replace("-", "").replace(":", "")
        path = write_hpl(scan(start, k), folder / f"VAD_999_{stamp[:8]}_{stamp[9:15]}.hpl")
        total += path.stat().st_size
    return total


def byte_compile(root: Path) -> None:
    """Byte-compile the ``cwproc`` of a checkout, as an install does: where
    ``PYTHONDONTWRITEBYTECODE`` is set no run writes ``.pyc`` files, and each timed
    process would compile the modules changed since the last compilation (about
    20 ms each)."""
    subprocess.run([sys.executable, "-m", "compileall", "-q", str(root / "cwproc")], check=True)


def run(cmd: list[str], env: dict | None = None) -> tuple[float, float, str, float]:
    """Wall time, CPU time (user + system, s), stderr and peak resident memory (MiB,
    ``ru_maxrss``) of one child process."""
    t0 = time.perf_counter()
    # run outside any checkout, so that ``python -c`` imports cwproc from ``PYTHONPATH``
    # (``--baseline``) or the installed one, never from the current directory
    proc = subprocess.Popen(
        cmd,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
        cwd=tempfile.gettempdir(),
    )
    err = proc.stderr.read() if proc.stderr else ""
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    if os.waitstatus_to_exitcode(status) != 0:
        raise SystemExit(f"{' '.join(cmd[:4])} ... failed: {err[-2000:]}")
    return wall, usage.ru_utime + usage.ru_stime, err, usage.ru_maxrss / 1024


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=2)
    parser.add_argument("--scans", type=int, default=int(86400 / PERIOD_S))
    parser.add_argument("--day-dir", type=Path, help="folder of the day's files (kept)")
    parser.add_argument(
        "--serial", action="store_true", help="also retrieve in one thread (CWPROC_READ_AHEAD=0)"
    )
    parser.add_argument(
        "--baseline", type=Path, help="another cwproc checkout to compare with (its root)"
    )
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="cwproc_bench_day_") as tmp:
        folder = (args.day_dir or Path(tmp) / "day").resolve()
        folder.mkdir(parents=True, exist_ok=True)
        t0 = time.perf_counter()
        held = sorted(folder.glob("*.hpl"))
        size = sum(p.stat().st_size for p in held) if held else write_day(folder, args.scans)
        n_files = len(held) or args.scans
        how = "reused" if held else f"written in {time.perf_counter() - t0:.0f} s"
        print(f"day: {n_files} scans of {RAYS} rays x {GATES} gates, one file each, "
              f"{size / 2**20:.0f} MiB ({how}); load average {os.getloadavg()[0]:.1f}")  # fmt: skip
        # this checkout's cwproc, whatever the interpreter has installed
        root = Path(__file__).resolve().parents[1]
        this = {**os.environ, "PYTHONPATH": str(root)}
        byte_compile(root)
        variants: dict[str, dict | None] = {"": this}
        if args.serial:
            variants["CWPROC_READ_AHEAD=0 "] = {**this, "CWPROC_READ_AHEAD": "0"}
        if args.baseline:
            baseline = str(args.baseline.resolve())
            variants[f"of {baseline} "] = {**os.environ, "PYTHONPATH": baseline}
            byte_compile(Path(baseline))
        reads: list[tuple[float, float, str, float]] = []
        retrieves: dict[str, list[tuple[float, float, str, float]]] = {k: [] for k in variants}
        peaks: dict[str, list[float]] = {k: [] for k in variants}
        for k in range(args.repeat):
            reads.append(run([sys.executable, "-c", _READ, str(folder)], this))
            for v, (name, env) in enumerate(variants.items()):
                out = Path(tmp) / f"out{k}_{v}"
                cmd = [sys.executable, "-m", "cwproc", "retrieve", str(folder), "-o", str(out)]
                got = run([*cmd, "-q", "-c", "streamline"], env)
                retrieves[name].append(got)
                peaks[name].append(got[3])
        rw, rc = min(r[0] for r in reads), min(r[1] for r in reads)
        print(f"  read_hpl of every file (process) {rw:7.2f} s wall, {rc:7.2f} s CPU")
        for name in variants:
            tw, tc = min(r[0] for r in retrieves[name]), min(r[1] for r in retrieves[name])
            print(f"  cwproc retrieve {name}(process) {tw:7.2f} s wall, {tc:7.2f} s CPU")
            print(f"  ratio retrieve / read            {tw / rw:7.2f} wall, {tc / rc:7.2f} CPU "
                  "(target <= 1.5)")  # fmt: skip
            pairs = [t[0] / r[0] for t, r in zip(retrieves[name], reads, strict=True)]
            each = ", ".join(f"{x:.2f}" for x in pairs)
            print(f"  ratio of each repeat (after its read) {each}; "
                  f"median {statistics.median(pairs):.2f}")  # fmt: skip
            print(f"  retrieve peak RSS                {max(peaks[name]):7.0f} MiB (target < 300)")
        if args.baseline:
            report_baseline(retrieves, peaks)
            out = [Path(tmp) / f"out{args.repeat - 1}_{v}" for v in range(len(variants))]
            for v, name in enumerate(list(variants)[:-1]):  # the baseline is the last
                same = same_products(out[v], out[-1])
                print(f"  products {name or 'of this checkout '}vs baseline    {same}")


def report_baseline(retrieves: dict[str, list], peaks: dict[str, list[float]]) -> None:
    """This checkout's retrieve against the baseline's, repeat by repeat (ratios)."""
    this, base = retrieves[""], retrieves[next(k for k in retrieves if k.startswith("of "))]
    walls = [a[0] / b[0] for a, b in zip(this, base, strict=True)]
    cpus = [a[1] / b[1] for a, b in zip(this, base, strict=True)]
    print(f"  this / baseline, each repeat      wall {', '.join(f'{x:.2f}' for x in walls)}; "
          f"CPU {', '.join(f'{x:.2f}' for x in cpus)}")  # fmt: skip
    base_peak = max(peaks[next(k for k in peaks if k.startswith("of "))])
    print(f"  peak RSS this / baseline          {max(peaks['']):.0f} / {base_peak:.0f} MiB")


#: largest difference of a float variable from the baseline's, relative to the largest
#: magnitude of the baseline's variable, still called round-off (a change of the order
#: of summation: a sum of 180 rays rounds at about 1e-14 of its terms)
ROUND_OFF = 1e-9


def same_products(ours: Path, theirs: Path) -> str:
    """'identical' when both folders hold the same product files whose variables are
    equal bit for bit (NaN where NaN); 'equal to round-off' when only float values
    differ, NaN where NaN and by at most :data:`ROUND_OFF` of the variable's largest
    magnitude (the largest such difference named); else which file and variable differ.
    """
    names = sorted(p.name for p in ours.glob("*.nc"))
    if not names or names != sorted(p.name for p in theirs.glob("*.nc")):
        return f"DIFFERENT files: {names} against {sorted(p.name for p in theirs.glob('*.nc'))}"
    worst = (0.0, "")
    for name in names:
        with netCDF4.Dataset(ours / name) as a, netCDF4.Dataset(theirs / name) as b:
            a.set_auto_mask(False)
            b.set_auto_mask(False)
            if sorted(a.variables) != sorted(b.variables):
                return f"DIFFERENT variables in {name}"
            for var in a.variables:
                x, y = a[var][...], b[var][...]
                nan = x.dtype.kind == "f" and y.dtype.kind == "f"
                if x.shape == y.shape and np.array_equal(x, y, equal_nan=nan):
                    continue
                relative = _relative_difference(x, y) if nan else np.inf
                if not relative <= ROUND_OFF:
                    return f"DIFFERENT: {name} {var} (largest difference {relative:.1e} relative)"
                worst = max(worst, (relative, f"{name} {var}"))
    if worst[1]:
        return (
            f"equal to round-off ({len(names)} files; largest difference {worst[0]:.1e} of "
            f"the variable's magnitude, {worst[1]}; every integer and flag bit for bit)"
        )
    return f"identical ({len(names)} files, every variable bit for bit)"


def _relative_difference(x: np.ndarray, y: np.ndarray) -> float:
    """Largest ``|x - y|`` over the largest ``|y|`` of the finite values (inf where the
    shapes, the NaN or the infinities differ)."""
    if x.shape != y.shape:
        return np.inf
    finite = np.isfinite(y)
    if not np.array_equal(x[~finite], y[~finite], equal_nan=True):
        return np.inf
    if not np.all(np.isfinite(x[finite])):
        return np.inf
    scale = float(np.max(np.abs(y[finite]), initial=0.0))
    diff = float(np.max(np.abs(x[finite] - y[finite]), initial=0.0))
    return diff / scale if scale > 0 else (0.0 if diff == 0 else np.inf)


if __name__ == "__main__":
    main()
