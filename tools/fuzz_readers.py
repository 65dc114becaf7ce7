"""Fuzz every reader with mutated copies of the shipped (simulated) samples (issue 34).

Each mutation is generated here from the samples in ``sample_data/`` and from a scan
NetCDF and a background file made from them (no real file is copied into the
project), and read with the reader of its format (all ten). Counted:

- **tracebacks**: anything but :class:`cwproc.errors.CwprocError` escaping a reader, or
  an error message that says "internal error", holds a line break or a Python
  traceback;
- **hangs**: a read that takes more than ``--timeout`` seconds (SIGALRM);
- **products for broken input**: a read that succeeds on a mutation that must be
  refused (a year outside the plausible window, a sparse body, NUL-filled data), or a
  dataset with a time outside the plausible window or the undamaged file's own span
  (an invented day);
- **impossible values marked good**: a value outside the physical range of its
  quantity and dataset kind (:func:`cwproc.io.ranges.ranges_for`), or an infinite one;
  and, for every ``--retrieve-every``-th mutation of a lidar sample, a product of
  ``cwproc retrieve`` with such a value or a missing wind with ``qc_flag`` 0.

All four must be zero. Run::

    python tools/fuzz_readers.py                      # 1,500 mutations (150 per format)
    python tools/fuzz_readers.py --per-format 20 --seed 3

Exit status 0 when every count is zero, 1 otherwise (the offending cases are printed).
"""

from __future__ import annotations

import argparse
import re
import signal
import sys
import tempfile
import time
import traceback
from collections import Counter
from pathlib import Path

import numpy as np

from cwproc.errors import CwprocError
from cwproc.io import read_file
from cwproc.io.ranges import ranges_for
from cwproc.io.timecheck import first_implausible

SAMPLE = Path(__file__).resolve().parents[1] / "sample_data"

#: format -> (sample, reader options, dataset kind)
SAMPLES: dict[str, tuple[Path, dict, str]] = {
    "hpl": (SAMPLE / "streamline" / "VAD_999_20240601_120000.hpl", {}, "scan"),
    "zephir": (SAMPLE / "zephir" / "Wind10_999@Y2024_M06_D01.ZPH.csv", {}, "wind_record"),
    "windcube": (SAMPLE / "windcube" / "WLS7-999_2024_06_01__00_00_00.sta", {}, "wind_record"),
    "toa5": (SAMPLE / "sonic" / "TOA5_999.ts_data_2024_06_01_1200.dat", {}, "sonic"),
    "tob1": (SAMPLE / "sonic" / "TOB1_999.ts_data_2024_06_01_1200.dat", {}, "sonic"),
    "ghg": (SAMPLE / "sonic" / "2024-06-01T120000_AIU-0999.data", {}, "sonic"),
    "meteo2": (SAMPLE / "sonic" / "meteo2_2024_06_01_1200.txt", {}, "sonic"),
    "gill": (
        SAMPLE / "sonic" / "gill_2024_06_01_1200.txt",
        {"start_time": "2024-06-01T12:00:00", "sampling_rate_hz": 10.0},
        "sonic",
    ),
}

#: bytes kept of each text sample (the damage is anywhere in them; reads stay fast)
KEEP = 60_000
NUMBER = re.compile(rb"-?\d+[.,]\d+")
YEAR = re.compile(rb"2024")
GHG_SECONDS = re.compile(rb"\t17172\d{5}\t")
#: mutations that must be refused whatever else: (name, refusal expected)
MUTATIONS: dict[str, bool] = {
    "cut": False,
    "flip": False,
    "delete_line": False,
    "duplicate_line": False,
    "absurd_number": False,
    "junk_appended": False,
    "bytes_inserted": False,
    "inf": False,
    "empty_field": False,
    "impossible_w": False,
    "garbage_block": False,
    "year_1430": True,
    "year_2590": True,
    "nul_body": True,
}


class Hang(Exception):
    """A read that did not end in time."""


def _alarm(signum, frame):
    raise Hang


def generated_samples(folder: Path) -> dict[str, tuple[Path, dict, str]]:
    """The two formats no sample ships, made here: a scan NetCDF of the Stream Line
    sample and a Stream Line background file (one value per gate, as the instrument
    writes them)."""
    from cwproc.io.halo import read_hpl
    from cwproc.io.scan_netcdf import write_scan_netcdf

    scan = write_scan_netcdf(read_hpl(SAMPLES["hpl"][0]), folder / "sample_scan.nc")
    background = folder / "Background_010624-120005.txt"
    background.write_text("".join(f"{16_800_000 + 37 * i}.125000\r\n" for i in range(200)))
    return {
        "scan_netcdf": (scan, {}, "scan"),
        "halo_background": (background, {}, "background"),
    }


def mutate(raw: bytes, name: str, rng: np.random.Generator, binary: bool) -> bytes:
    """One mutation ``name`` of ``raw`` at a random place (``rng``)."""
    at = int(rng.integers(0, max(len(raw), 1)))
    if name == "cut":
        return raw[:at]
    if name == "flip":
        n = int(rng.integers(1, 9))
        return (
            raw[:at]
            + bytes(b ^ int(rng.integers(1, 256)) for b in raw[at : at + n])
            + raw[at + n :]
        )
    if name in ("delete_line", "duplicate_line"):
        start = raw.rfind(b"\n", 0, at) + 1
        end = raw.find(b"\n", at)
        end = len(raw) if end < 0 else end + 1
        if name == "delete_line":
            return raw[:start] + raw[end:]
        return raw[:start] + raw[start:end] + raw[start:]
    if name == "bytes_inserted":
        return (
            raw[:at]
            + bytes(rng.integers(0, 256, int(rng.integers(1, 40)), dtype=np.uint8))
            + raw[at:]
        )
    if name == "junk_appended":
        return raw + bytes(rng.integers(0, 256, int(rng.integers(1, 200)), dtype=np.uint8))
    if name == "garbage_block":  # ten records' worth of random bytes (binary) or lines
        size = 320 if binary else 0
        if not binary:
            start = raw.rfind(b"\n", 0, at) + 1
            end = raw.find(b"\n", at)
            line = raw[start : end + 1] if end >= 0 else raw[start:]
            stamps = [
                YEAR.sub(str(int(rng.integers(2000, 2026))).encode(), line) for _ in range(10)
            ]
            return raw[:start] + b"".join(stamps) + raw[start:]
        return raw[:at] + bytes(rng.integers(0, 256, size, dtype=np.uint8)) + raw[at:]
    if name in ("year_1430", "year_2590"):
        year = int(name[-4:])
        if GHG_SECONDS.search(raw):  # LI-COR: the time is the Unix seconds field
            seconds = int((np.datetime64(f"{year}-06-01", "s") - np.datetime64(0, "s")).astype(int))
            return GHG_SECONDS.sub(f"\t{seconds}\t".encode(), raw)
        return YEAR.sub(str(year).encode(), raw)
    if name == "nul_body":
        half = len(raw) // 2
        return raw[:half] + b"\x00" * (len(raw) - half)
    numbers = list(NUMBER.finditer(raw))
    if not numbers:
        return raw
    m = numbers[int(rng.integers(0, len(numbers)))]
    text = raw[m.start() : m.end()]
    comma = b"," in text
    value = {
        "absurd_number": b"1e308",
        "inf": rng.choice([b"inf", b"-inf", b"Infinity"]),
        "empty_field": b"",
        "impossible_w": b"-50.0",
    }[name]
    if comma:
        value = value.replace(b".", b",")
    return raw[: m.start()] + value + raw[m.end() :]


def own_span(path: Path, options: dict) -> tuple[np.datetime64, np.datetime64]:
    """First and last time of the undamaged file."""
    t = read_file(path, **options)["time"].values
    return t.min(), t.max()


def dataset_problems(ds, kind: str, span) -> list[str]:
    """What is false in a dataset a reader returned for a damaged file."""
    found = []
    for var, (low, high) in ranges_for(kind).items():
        if var in ds and ds[var].dtype.kind == "f":
            values = ds[var].values
            with np.errstate(invalid="ignore"):
                bad = np.isinf(values) | (values < low) | (values > high)
            if bad.any():
                found.append(f"impossible {var} {values[bad][0]!r}")
    if "time" in ds.coords or "time" in ds:
        times = ds["time"].values
        if first_implausible(times) is not None:
            found.append("implausible time")
        times = times[~np.isnat(times)]
        slack = np.timedelta64(1, "s")
        if times.size and (times.min() < span[0] - slack or times.max() > span[1] + slack):
            found.append(f"time {times.min()}..{times.max()} outside the file's own span")
    return found


def product_problems(out: Path, kind: str) -> list[str]:
    """What is false in the products ``cwproc retrieve`` wrote."""
    import xarray as xr

    found = []
    for path in out.glob("*.nc"):
        with xr.open_dataset(path) as ds:
            for var, (low, high) in ranges_for(kind).items():
                if var in ds and ds[var].dtype.kind == "f":
                    values = ds[var].values
                    with np.errstate(invalid="ignore"):
                        if np.any(np.isinf(values) | (values < low) | (values > high)):
                            found.append(f"{path.name}: impossible {var}")
            if "qc_flag" in ds:
                good = ds["qc_flag"].values == 0
                for var in ("u", "v", "w", "wind_speed", "wind_direction"):
                    if var in ds and ds[var].dims == ds["qc_flag"].dims:
                        if np.any(~np.isfinite(ds[var].values) & good):
                            found.append(f"{path.name}: missing {var} flagged good")
    return found


def check_retrieve(path: Path, out: Path, preset: str, kind: str, case: str, counts) -> None:
    """``cwproc retrieve`` on one mutated file: exit 0 or 1, no traceback, sane products."""
    from click.testing import CliRunner

    from cwproc.cli import main

    result = CliRunner().invoke(main, ["retrieve", str(path), "-o", str(out), "-c", preset, "-q"])
    counts["retrieved"] += 1
    if (
        result.exit_code not in (0, 1)
        or "Traceback" in result.output
        or (result.exception and not isinstance(result.exception, SystemExit))
    ):
        counts["tracebacks"] += 1
        print(f"RETRIEVE {case}: exit {result.exit_code} {result.output[:300]}")
    for p in product_problems(out, kind):
        counts["impossible values marked good"] += 1
        print(f"FALSE PRODUCT {case}: {p}")


def run(per_format: int, seed: int, timeout_s: int, retrieve_every: int) -> Counter:
    """Fuzz every format; print the offending cases; return the counts."""
    counts: Counter = Counter()
    rng = np.random.default_rng(seed)
    names = list(MUTATIONS)
    signal.signal(signal.SIGALRM, _alarm)
    presets = {"hpl": "streamline", "zephir": "zephir300", "windcube": "windcube"}
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        formats = {**SAMPLES, **generated_samples(folder)}
        for fmt, (path, sample_options, kind) in formats.items():
            raw = path.read_bytes()
            counts["formats"] += 1
            binary = fmt in ("tob1", "scan_netcdf")
            if not binary:
                raw = raw[:KEEP]
            span = own_span(path, sample_options)
            for k in range(per_format):
                mutation = names[k % len(names)]
                options = sample_options
                if mutation.startswith("year_") and fmt in (
                    "tob1",
                    "scan_netcdf",
                    "halo_background",
                ):
                    mutation = "flip"  # 1990 + an unsigned 32-bit count: 2126 at most
                bad = folder / f"{k}_{path.name}"
                if mutation.startswith("year_") and fmt == "gill":  # its time is an option
                    options = {**options, "start_time": f"{mutation[-4:]}-06-01T12:00:00"}
                    bad.write_bytes(raw)
                else:
                    bad.write_bytes(mutate(raw, mutation, rng, binary))
                counts["mutations"] += 1
                case = f"{fmt} #{k} {mutation}"
                if fmt in presets and k % retrieve_every == 0:
                    check_retrieve(bad, folder / f"out_{fmt}_{k}", presets[fmt], kind, case, counts)
                signal.alarm(timeout_s)
                try:
                    ds = read_file(bad, **options)
                except Hang:
                    counts["hangs"] += 1
                    print(f"HANG {case}")
                    continue
                except CwprocError as exc:
                    text = str(exc)
                    if "internal error" in text or "\n" in text or "Traceback" in text:
                        counts["tracebacks"] += 1
                        print(f"BAD MESSAGE {case}: {text[:200]}")
                    else:
                        counts["refused"] += 1
                    continue
                except Exception:
                    counts["tracebacks"] += 1
                    print(f"TRACEBACK {case}:\n{traceback.format_exc()}")
                    continue
                finally:
                    signal.alarm(0)
                counts["read"] += 1
                if MUTATIONS[mutation] and not (mutation == "nul_body" and binary):
                    # (zero records of a binary log are dropped with a note: the half
                    # before them is read, checked below to hold nothing invented)
                    counts["products for broken input"] += 1
                    print(f"NOT REFUSED {case}")
                problems = dataset_problems(ds, kind, span)
                for p in problems:
                    key = (
                        "impossible values marked good"
                        if "impossible" in p
                        else "products for broken input"
                    )
                    counts[key] += 1
                    print(f"FALSE {case}: {p}")
                bad.unlink()
    return counts


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--per-format", type=int, default=150, help="mutations per format")
    parser.add_argument("--seed", type=int, default=34)
    parser.add_argument("--timeout", type=int, default=60, help="seconds before a read is a hang")
    parser.add_argument("--retrieve-every", type=int, default=5)
    args = parser.parse_args()
    t0 = time.process_time()
    counts = run(args.per_format, args.seed, args.timeout, args.retrieve_every)
    zero = ("tracebacks", "hangs", "products for broken input", "impossible values marked good")
    print(
        f"{counts['mutations']} mutations of {counts['formats']} formats "
        f"({counts['read']} read, {counts['refused']} refused with a clear error, "
        f"{counts['retrieved']} through cwproc retrieve) in {time.process_time() - t0:.0f} s CPU: "
        + ", ".join(f"{k} {counts[k]}" for k in zero)
    )
    sys.exit(0 if all(counts[k] == 0 for k in zero) else 1)


if __name__ == "__main__":
    main()
