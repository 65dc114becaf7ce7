"""The benchmark lock lists the shipped inputs as they are (issue 15.5)."""

import importlib.util
from pathlib import Path

LOCK_SCRIPT = Path(__file__).resolve().parents[1] / "benchmarks" / "lock.py"


def test_shipped_benchmark_inputs_match_the_lock():
    spec = importlib.util.spec_from_file_location("bench_lock", LOCK_SCRIPT)
    lock_module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(lock_module)
    import json

    lock = json.loads(lock_module.LOCK.read_text())
    inputs = {k: v for k, v in lock_module.current_inputs().items() if k.startswith("sample")}
    assert inputs, "no shipped samples found"
    assert lock_module.differences(lock, inputs) == []
    assert lock["figures"], "the lock holds the last measured figures"
