"""Build the A-function tables shipped inside the package (run at release).

The ε retrieval needs a table of the A-functions of Smalikho (2020), eqs. 15-17, for
each instrument configuration (probe, elevation, azimuth step, lags, spectrum model);
building one takes tens of seconds to minutes. So that a new user never waits, the
tables of the shipped presets on the shipped samples and the README's tour are built
here and shipped in ``cwproc/atables/`` (package data):

    python tools/build_atables.py            # rebuild cwproc/atables/*.npz

Each job below runs with an empty cache (``XDG_CACHE_HOME`` in a temporary folder); the
tables it builds are copied, compressed, into ``cwproc/atables/`` under their cache
key, and ``cwproc/atables/MANIFEST.txt`` lists which job needed which table. Run it
after any change to the table numerics (``TABLE_VERSION``), the grid or the presets;
``tests/physics/test_shipped_atables.py`` checks that every shipped table is the one a
rebuild gives.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
TARGET = ROOT / "cwproc" / "atables"

#: name -> shell commands (run from a temporary folder; SAMPLE is the sample_data path)
JOBS: dict[str, list[str]] = {
    "streamline preset, sample_data (README main job)": [
        "cwproc retrieve {sample} -c {sample}/site.toml -o out/",
    ],
    "streamline preset, README simulate lidar": [
        "cwproc simulate lidar -o sim/ --hours 0.1 --wind 8 --seed 3",
        "cwproc retrieve sim/data -o sim_out/",
    ],
    "zephir300 preset, simulate lidar --instrument zephir": [
        "cwproc simulate lidar --instrument zephir -o zsim/ --hours 0.05",
        "cwproc retrieve -c zephir300 zsim/data -o zout/",
    ],
    "banakh1999 preset, simulate lidar --instrument cw": [
        "cwproc simulate lidar --instrument cw -o csim/ --hours 0.05",
        "cwproc retrieve -c banakh1999 csim/data -o cout/",
    ],
}


def run_job(commands: list[str], cache: Path, workdir: Path) -> list[Path]:
    """Run one job with ``cache`` as the only table cache; the tables it built."""
    env = {**os.environ, "XDG_CACHE_HOME": str(cache)}
    bindir = Path(sys.executable).parent
    env["PATH"] = f"{bindir}{os.pathsep}{env.get('PATH', '')}"
    for command in commands:
        line = command.format(sample=ROOT / "sample_data")
        print(f"  $ {line}", flush=True)
        subprocess.run(line, shell=True, check=True, cwd=workdir, env=env)
    return sorted((cache / "cwproc").glob("atable-*.npz"))


def ship(table: Path, target: Path) -> Path:
    """Copy ``table`` into ``target`` compressed (same arrays, same key and name)."""
    with np.load(table, allow_pickle=False) as data:
        arrays = {name: data[name] for name in data.files}
    out = target / table.name
    np.savez_compressed(out, **arrays)
    return out


def main() -> int:
    TARGET.mkdir(exist_ok=True)
    for old in TARGET.glob("atable-*.npz"):
        old.unlink()
    manifest = ["# table file -> the job that needs it (tools/build_atables.py)"]
    with tempfile.TemporaryDirectory() as tmp:
        for k, (name, commands) in enumerate(JOBS.items()):
            print(f"{name}:", flush=True)
            cache = Path(tmp) / f"cache{k}"
            work = Path(tmp) / f"work{k}"
            work.mkdir()
            for table in run_job(commands, cache, work):
                shipped = ship(table, TARGET)
                manifest.append(f"{shipped.name}  {name}")
                print(f"  shipped {shipped.relative_to(ROOT)} ({shipped.stat().st_size} B)")
    (TARGET / "MANIFEST.txt").write_text("\n".join(manifest) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
