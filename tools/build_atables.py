"""Build the A-function tables shipped inside the package (run at release).

The ε retrieval needs a table of the A-functions of Smalikho (2020), eqs. 15-17, for
each instrument configuration (probe, elevation, azimuth step, lags, spectrum model).
So that the README's commands never build one, the tables of the shipped presets on the
shipped samples and the README's tour are built here and shipped in ``cwproc/atables/``
(package data):

    python tools/build_atables.py            # run the jobs below, ship what they request
    python tools/build_atables.py --rebuild  # rebuild the shipped tables from their
                                             # stored parameters (after a code change)
    python tools/build_atables.py --rekey    # ship the same arrays under the key of
                                             # the current code (after a move of code
                                             # that leaves the numbers alone; checked)

Each job runs with an empty cache (``XDG_CACHE_HOME`` in a temporary folder) and the
code of this checkout; every table it requests is recorded with its parameters, built,
and copied, compressed, into ``cwproc/atables/`` under its cache key with its parameters
(``params``, JSON) inside. ``cwproc/atables/MANIFEST.txt`` lists which job needed which
table. The cache key holds a hash of the code of the physics modules the build uses
(:func:`cwproc.tables.store.code_digest`), so any change of that code makes the
shipped tables stale: ``--rebuild`` then builds them again from the stored parameters,
without the jobs; ``tests/physics/test_shipped_atables.py`` fails until it is run.
When the code changed without changing the numbers (a module moved or renamed, a
docstring edited), ``--rekey`` keeps the shipped arrays byte for byte: it rebuilds each
table with the current code, requires it to equal the shipped one within the
tolerance of ``test_shipped_tables_equal_a_rebuild`` (the last bits of another host's
arithmetic), and ships the old arrays under the new key; a table that differs more
stops it, and ``--rebuild`` is then the way.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
TARGET = ROOT / "cwproc" / "atables"

#: name -> cwproc command lines (run from a temporary folder; {sample}: sample_data)
JOBS: dict[str, list[str]] = {
    "streamline preset, sample_data (README main job)": [
        "retrieve {sample} -c {sample}/site.toml -o out/",
    ],
    "streamline preset, README simulate lidar": [
        "simulate lidar -o sim/ --hours 0.1 --wind 8 --seed 3",
        "retrieve sim/data -o sim_out/",
    ],
    "zephir300 preset, simulate lidar --instrument zephir": [
        "simulate lidar --instrument zephir -o zsim/ --hours 0.05",
        "retrieve -c zephir300 zsim/data -o zout/",
    ],
    "banakh1999 preset, simulate lidar --instrument cw": [
        "simulate lidar --instrument cw -o csim/ --hours 0.05",
        "retrieve -c banakh1999 csim/data -o cout/",
    ],
}

#: runs ``cwproc`` with every table request appended to $CWPROC_ATABLE_LOG (JSON lines)
RECORDER = """
import json, os, sys
from cwproc.tables import atable
key = atable.table_key
def recorded(params):
    with open(os.environ["CWPROC_ATABLE_LOG"], "a") as log:
        log.write(json.dumps(params) + "\\n")
    return key(params)
atable.table_key = recorded
from cwproc.cli import main
sys.argv[0] = "cwproc"
main()
"""


def run_job(commands: list[str], cache: Path, workdir: Path) -> list[dict]:
    """Run one job with ``cache`` as the only table cache; the parameters of its tables."""
    log = workdir / "atables.jsonl"
    env = {**os.environ, "XDG_CACHE_HOME": str(cache), "CWPROC_ATABLE_LOG": str(log)}
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), env.get("PYTHONPATH", "")])
    for command in commands:
        args = command.format(sample=ROOT / "sample_data").split()
        print(f"  $ cwproc {' '.join(args)}", flush=True)
        subprocess.run([sys.executable, "-c", RECORDER, *args], check=True, cwd=workdir, env=env)
    if not log.exists():
        return []
    return [json.loads(line) for line in log.read_text().splitlines() if line.strip()]


def ship(params: dict, target: Path, built: Path | None = None) -> Path:
    """The table of ``params`` (from the folder ``built`` when there, else built), written
    into ``target`` compressed, with ``params`` inside."""
    from cwproc.tables import atable

    key = atable.table_key(params)
    with tempfile.TemporaryDirectory() as tmp:
        path = None if built is None else built / f"atable-{key}.npz"
        if path is None or not path.exists():
            table = atable.build_a_table(atable.probe_from_params(params["probe"]), params)
            path = Path(tmp) / f"atable-{key}.npz"
            atable.save_table(table, path, key)
        with np.load(path, allow_pickle=False) as data:
            arrays = {name: data[name] for name in data.files}
    arrays["params"] = np.array(json.dumps(params, sort_keys=True))
    out = target / path.name
    np.savez_compressed(out, **arrays)
    return out


def stored(target: Path) -> list[tuple[dict, str, None]]:
    """``(params, job, None)`` of every shipped table listed in the manifest."""
    out = []
    for line in (target / "MANIFEST.txt").read_text().splitlines():
        if not line.strip() or line.startswith("#"):
            continue
        name, job = line.split(maxsplit=1)
        with np.load(target / name, allow_pickle=False) as data:
            out.append((json.loads(str(data["params"])), job, None))
    return out


def write(entries: list[tuple[dict, str, Path | None]], target: Path) -> None:
    """Ship the tables of ``entries`` (``(params, job, cache)``) and write the manifest;
    a table requested by several jobs is shipped once, listed under the first."""
    from cwproc.tables import atable

    target.mkdir(exist_ok=True)
    for old in target.glob("atable-*.npz"):
        old.unlink()
    manifest = ["# table file -> the job that needs it (tools/build_atables.py)"]
    done = set()
    for params, job, built in entries:
        params = {**params, "code": atable.code_version()}
        if atable.table_key(params) in done:
            continue
        done.add(atable.table_key(params))
        shipped = ship(params, target, built)
        manifest.append(f"{shipped.name}  {job}")
        print(f"  shipped {shipped.relative_to(ROOT)} ({shipped.stat().st_size} B)", flush=True)
    (target / "MANIFEST.txt").write_text("\n".join(manifest) + "\n")


#: a rebuild equals a shipped table within these (test_shipped_tables_equal_a_rebuild)
REKEY_RTOL, REKEY_ATOL = 1e-7, 1e-12


def rekeyed(target: Path, built: Path) -> list[tuple[dict, str, Path | None]]:
    """The shipped tables of ``target``, their arrays written into ``built`` under the
    key of the current code after a rebuild agreed with them (``ValueError`` if not)."""
    from cwproc.tables import atable

    out: list[tuple[dict, str, Path | None]] = []
    for params, job, _ in stored(target):
        with np.load(target / f"atable-{atable.table_key(params)}.npz") as data:
            arrays = {name: data[name] for name in data.files if name != "params"}
        fresh = {**params, "code": atable.code_version()}
        table = atable.build_a_table(atable.probe_from_params(params["probe"]), fresh)
        for name in ("log_a1", "log_a2", "bins_a2", "scale_bins"):
            now = getattr(table, name)
            now = np.zeros(0) if now is None else now
            if now.shape != arrays[name].shape or not np.allclose(
                now, arrays[name], rtol=REKEY_RTOL, atol=REKEY_ATOL
            ):
                raise ValueError(f"{job}: {name} changed with the code; use --rebuild")
        arrays["key"] = np.array(atable.table_key(fresh))
        np.savez(built / f"atable-{atable.table_key(fresh)}.npz", **arrays)
        out.append((params, job, built))
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rebuild", action="store_true", help="from the stored parameters")
    parser.add_argument("--rekey", action="store_true", help="same arrays, current code's key")
    args = parser.parse_args()
    sys.path.insert(0, str(ROOT))
    if args.rebuild:
        write(stored(TARGET), TARGET)
        return 0
    if args.rekey:
        with tempfile.TemporaryDirectory() as tmp:
            write(rekeyed(TARGET, Path(tmp)), TARGET)
        return 0
    entries: list[tuple[dict, str, Path | None]] = []
    with tempfile.TemporaryDirectory() as tmp:
        for k, (name, commands) in enumerate(JOBS.items()):
            print(f"{name}:", flush=True)
            work, cache = Path(tmp) / f"work{k}", Path(tmp) / f"cache{k}"
            work.mkdir()
            found = run_job(commands, cache, work)
            entries.extend((p, name, cache / "cwproc") for p in found)
        write(entries, TARGET)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
