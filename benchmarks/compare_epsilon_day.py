"""The ε stage of this checkout against another on the benchmark days: products and CPU time.

Runs :func:`cwproc.stages.epsilon.estimate_epsilon` on the two synthetic days of
``bench_epsilon_day.py`` (the 24-ray step-stare VAD, dwell fraction 0.45, and the
180-ray continuous scan; von Kármán, or ``--model``) once with this checkout's
``cwproc`` and once with the reference checkout's (``--ref``, default ``/work/main``),
each in its own process (``PYTHONPATH``), and

- compares every variable, coordinate and attribute of the two products: bit for bit
  (NaN equal to NaN), else the largest relative difference is printed and the exit
  status is 1 when it exceeds ``--rtol`` (default 0: bit-identical required);
- with ``--rounds N``, times the warm stage (CPU seconds, ``time.process_time``, best of
  ``--repeat``) of both checkouts alternately ``N`` times, so that the load of a shared
  box falls on both alike, and prints the ratio of the two; ``--fresh`` times each run
  without the per-geometry arrays an earlier call of the process kept (a process's first
  day of a scan geometry, warm A-tables).

Run::

    OMP_NUM_THREADS=1 python benchmarks/compare_epsilon_day.py --cache-dir DIR
    OMP_NUM_THREADS=1 python benchmarks/compare_epsilon_day.py --cache-dir DIR --rounds 3
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
#: (label, rays, ray period s, lags) of the two days of bench_epsilon_day.py
DAYS = (("24-ray VAD", 24, 3.0, 3), ("180-ray", 180, 0.2, 4))


def _worker(out: Path, cache_dir: str, repeat: int, fresh: bool, model: str) -> None:
    """Products of both days (``out``: .npz of every variable and a JSON of attributes)
    and the best warm CPU time of each day, printed as JSON; ``fresh``: every timed run
    without the arrays an earlier call of the process kept per scan geometry
    (:func:`cwproc.stages.epsilon.records.process_memo`, where the checkout has it)."""
    from bench_epsilon_day import synthetic_day

    import cwproc
    from cwproc.physics.transfer import PulsedProbe
    from cwproc.stages.epsilon import estimate_epsilon, records

    probe = PulsedProbe(15.3, 18.0)
    options = {"cache_dir": cache_dir}
    arrays, attrs, cpu = {}, {}, {}
    for label, n_rays, ray_s, n_lags in DAYS:
        sf = synthetic_day(n_rays, ray_s, n_lags)

        def run(sf=sf):
            return estimate_epsilon(
                sf, probe=probe, lag_number=3, model=model, table_options=options
            )

        product = run()  # tables warm (built here if the cache is cold)
        best = np.inf
        for _ in range(repeat):
            if fresh and hasattr(records, "_PROCESS_MEMOS"):
                records._PROCESS_MEMOS.clear()
            c0 = time.process_time()
            product = run()
            best = min(best, time.process_time() - c0)
        cpu[label] = best
        attrs[label] = {"": repr(sorted(product.attrs.items()))}
        for name, var in product.variables.items():
            arrays[f"{label}/{name}"] = var.values
            attrs[label][name] = repr((var.dims, sorted(var.attrs.items())))
    np.savez(out, **arrays)
    out.with_suffix(".json").write_text(json.dumps(attrs))
    print(json.dumps({"cwproc": str(Path(cwproc.__file__).parent), "cpu": cpu}))


def _run(checkout: Path, out: Path, cache_dir: str, repeat: int, fresh: bool, model: str) -> dict:
    env = {**os.environ, "PYTHONPATH": str(checkout), "OMP_NUM_THREADS": "1"}
    args = [sys.executable, str(Path(__file__)), "--worker", str(out), "--cache-dir", cache_dir]
    args += ["--model", model] + (["--fresh"] if fresh else [])
    done = subprocess.run(
        [*args, "--repeat", str(repeat)], env=env, capture_output=True, text=True, check=False
    )
    if done.returncode:
        raise SystemExit(f"{checkout}: the worker failed:\n{done.stderr[-2000:]}")
    result = json.loads(done.stdout.strip().splitlines()[-1])
    if Path(result["cwproc"]).resolve() != (checkout / "cwproc").resolve():
        raise SystemExit(f"{checkout}: the worker imported {result['cwproc']}")
    return result


def _relative(a: np.ndarray, b: np.ndarray) -> float:
    """Largest ``|a - b| / max(|a|, |b|)`` over the entries that differ (inf where one
    is NaN and the other not)."""
    if a.dtype.kind not in "fc":
        return 0.0 if np.array_equal(a, b) else np.inf
    nan_a, nan_b = np.isnan(a), np.isnan(b)
    if np.any(nan_a != nan_b):
        return np.inf
    ok = ~nan_a & (a != b)
    if not ok.any():
        return 0.0
    return float(np.max(np.abs(a[ok] - b[ok]) / np.maximum(np.abs(a[ok]), np.abs(b[ok]))))


def compare(this: Path, ref: Path, rtol: float) -> bool:
    """Print the variables of the two products that differ; whether all are within ``rtol``."""
    a, b = np.load(this), np.load(ref)
    attrs_a = json.loads(this.with_suffix(".json").read_text())
    attrs_b = json.loads(ref.with_suffix(".json").read_text())
    ok = True
    if sorted(a.files) != sorted(b.files):
        print("variables differ:", sorted(set(a.files) ^ set(b.files)))
        ok = False
    identical = 0
    for name in sorted(set(a.files) & set(b.files)):
        x, y = a[name], b[name]
        if x.shape != y.shape or x.dtype != y.dtype:
            print(f"{name}: shape/dtype {x.shape} {x.dtype} against {y.shape} {y.dtype}")
            ok = False
        elif np.array_equal(x, y, equal_nan=x.dtype.kind in "fc"):
            identical += 1
        else:
            rel = _relative(x, y)
            print(f"{name}: differs, largest relative difference {rel:.3g}")
            ok &= rel <= rtol
    for label, per_var in attrs_a.items():
        for name, text in per_var.items():
            if attrs_b.get(label, {}).get(name) != text:
                print(f"{label}/{name}: attributes differ")
                ok = False
    print(f"{identical} of {len(a.files)} variables bit-identical")
    return ok


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ref", type=Path, default=Path("/work/main"))
    parser.add_argument("--cache-dir", required=True)
    parser.add_argument("--rounds", type=int, default=1)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--rtol", type=float, default=0.0)
    parser.add_argument("--model", default="von_karman")
    parser.add_argument(
        "--fresh", action="store_true", help="time without the per-geometry process memo"
    )
    parser.add_argument("--worker", type=Path, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker is not None:
        _worker(args.worker, args.cache_dir, args.repeat, args.fresh, args.model)
        return 0
    times: dict[str, list[dict]] = {"this": [], "ref": []}
    with tempfile.TemporaryDirectory() as tmp:
        files = {key: Path(tmp) / f"{key}.npz" for key in times}
        for _ in range(args.rounds):
            for key, checkout in (("this", ROOT), ("ref", args.ref)):
                run = _run(
                    checkout, files[key], args.cache_dir, args.repeat, args.fresh, args.model
                )
                times[key].append(run["cpu"])
        same = compare(files["this"], files["ref"], args.rtol)
    load = os.getloadavg()
    print(
        f"CPU s, warm, best of {args.repeat}, rounds alternated (load {load[0]:.1f} {load[1]:.1f})"
    )
    for label, *_ in DAYS:
        mine = [t[label] for t in times["this"]]
        ref = [t[label] for t in times["ref"]]
        ratio = [m / r for m, r in zip(mine, ref, strict=True)]
        print(
            f"  {label:11s} this {' '.join(f'{t:.3f}' for t in mine)}  "
            f"ref {' '.join(f'{t:.3f}' for t in ref)}  ratio {' '.join(f'{r:.2f}' for r in ratio)}"
        )
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
