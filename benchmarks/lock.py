"""The benchmark lock: checksums of the benchmarks' inputs and their last figures (issue 15).

``benchmarks/LOCK.json`` records, for review,

- ``inputs``: the SHA-256 of every file the benchmarks read (the shipped samples, and
  the real instrument files of ``../shared/real_data`` when present);
- ``figures``: the last measured figures of each benchmark, with the command that
  prints them, the date and the machine (written by hand from the benchmark's output:
  a change of a figure is then a visible diff in review).

Run::

    python benchmarks/lock.py --check           # exit 1 when an input differs from the lock
    python benchmarks/lock.py --update-inputs   # record the current inputs
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LOCK = ROOT / "benchmarks" / "LOCK.json"
SHARED = ROOT.parent / "shared" / "real_data"


def sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def current_inputs() -> dict[str, str]:
    """``{relative path: sha256}`` of the samples and (when present) the real files."""
    out = {}
    for path in sorted((ROOT / "sample_data").rglob("*")):
        if path.is_file():
            out[f"sample_data/{path.relative_to(ROOT / 'sample_data').as_posix()}"] = sha256(path)
    if SHARED.is_dir():
        for path in sorted(SHARED.rglob("*")):
            if path.is_file() and path.name not in ("SHA256SUMS",):
                out[f"../shared/real_data/{path.relative_to(SHARED).as_posix()}"] = sha256(path)
    return out


def differences(lock: dict, inputs: dict[str, str]) -> list[str]:
    """Inputs whose checksum differs from the lock, or that the lock does not know.

    Real files absent on this machine (no ``../shared``) are not differences.
    """
    recorded = lock.get("inputs", {})
    lines = []
    for name, digest in inputs.items():
        if recorded.get(name) != digest:
            lines.append(f"{name}: {'changed' if name in recorded else 'not in the lock'}")
    for name in recorded:
        if name not in inputs and not name.startswith("../shared/"):
            lines.append(f"{name}: missing")
    return lines


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true")
    parser.add_argument("--update-inputs", action="store_true")
    args = parser.parse_args()
    lock = json.loads(LOCK.read_text()) if LOCK.exists() else {"inputs": {}, "figures": {}}
    inputs = current_inputs()
    if args.update_inputs:
        lock["inputs"] = {**lock.get("inputs", {}), **inputs}
        LOCK.write_text(json.dumps(lock, indent=1, sort_keys=True) + "\n")
        print(f"recorded {len(inputs)} inputs in {LOCK}")
        return 0
    problems = differences(lock, inputs)
    for line in problems:
        print(line)
    if not problems:
        print(f"{len(inputs)} inputs match {LOCK.name}")
    return 1 if (args.check and problems) else 0


if __name__ == "__main__":
    sys.exit(main())
