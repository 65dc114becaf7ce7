"""``cwproc batch`` under faults: kill -9, concurrent runs, bad inputs, write errors,
and the same archive through the serial, ``--workers`` and ``--scheduler`` executors.

Most tests use the toy backend of ``test_batch.py`` (inputs whose every byte the test
controls, products written by the real atomic writer); the executor comparison and a
second kill -9 test run the real pipeline (Stream Line reader, qc, vad) on synthetic
``.hpl`` files with a known wind.
"""

from __future__ import annotations

import errno
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from cwproc.batch import (
    STATE_DIR,
    LockBusyError,
    close_client,
    dask_client,
    load_ledger,
    run_batch,
)
from cwproc.config import load_config
from cwproc.io.netcdf import read_product

TESTS = Path(__file__).resolve().parent
sys.path.insert(0, str(TESTS))

from test_batch import (  # noqa: E402
    _missing_pipeline_modules,
    read_toy,
    run_toy,
    synthetic_vad_scans,
    toy_archive,
    wind_only_config,
    write_toy,
)

#: global attributes that hold the processing time (differ between any two runs)
DATE_ATTRS = {"history", "date_created", "date_modified", "date_issued", "date_metadata_modified"}
DATE_ATTRS.add("file_uuid")  # ACTRIS/Cloudnet: every file written has its own

_SCRIPT = """
import os, sys
sys.path.insert(0, {tests!r})
from test_batch import run_toy
report = run_toy({inputs!r}, {outdir!r})
print("done", len(report.processed), flush=True)
"""


def start_toy_run(inputs: Path, outdir: Path, journal: Path, sleep_s: float):
    """A batch run with the toy backend in a subprocess, ``sleep_s`` per unit."""
    env = dict(os.environ, CWPROC_TOY_SLEEP=str(sleep_s), CWPROC_TOY_JOURNAL=str(journal))
    script = _SCRIPT.format(tests=str(TESTS), inputs=str(inputs), outdir=str(outdir))
    return subprocess.Popen(
        [sys.executable, "-c", script],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def wait_for(predicate, proc: subprocess.Popen, poll_s: float = 0.02) -> None:
    """Wait for the event ``predicate`` while ``proc`` runs: no clock (issue 34.8).

    A fixed 30 s deadline failed on a busy machine although nothing was wrong. The
    process ends by itself (its units are few and short), so the wait ends too: with
    the event, or with an error when the process ended first (its output attached).
    """
    while not predicate():
        if proc.poll() is not None:
            if predicate():
                return
            out, err = proc.communicate()
            raise AssertionError(
                f"the run ended (status {proc.returncode}) before the event: {out}{err}"
            )
        time.sleep(poll_s)


def ledger_units(outdir: Path) -> dict:
    """The units of the ledger as a reader would see it now (snapshot + journal)."""
    path = outdir / STATE_DIR / "ledger.json"
    if not path.exists():
        return {}
    return load_ledger(path).units


def leftovers(outdir: Path) -> list[Path]:
    return sorted(outdir.rglob("*.tmp"))


def assert_products_open(outdir: Path) -> list[Path]:
    products = sorted(outdir.glob("*.nc"))
    for path in products:
        with xr.open_dataset(path) as ds:
            ds.load()
    return products


def day_archive(root: Path, n_days: int) -> list[Path]:
    """One toy file per day for ``n_days`` days."""
    rng = np.random.default_rng(99)
    return [
        write_toy(root / f"d{d:02d}.txt", "K", f"2024-02-{d + 1:02d}", rng.normal(size=10))
        for d in range(n_days)
    ]


# --------------------------------------------------------------------------------------
# kill -9 and concurrent runs
# --------------------------------------------------------------------------------------


def test_kill_9_mid_run_then_rerun_does_everything_exactly_once(tmp_path, monkeypatch):
    inputs, out, journal = tmp_path / "in", tmp_path / "out", tmp_path / "journal"
    day_archive(inputs, 8)
    proc = start_toy_run(inputs, out, journal, sleep_s=0.25)
    try:
        wait_for(lambda: len(ledger_units(out)) >= 2, proc)
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    assert proc.returncode == -signal.SIGKILL
    done_before = set(ledger_units(out))
    assert 2 <= len(done_before) < 8
    # a temporary file as the writer leaves it when killed inside to_netcdf
    (out / ".toy_K_20240208_wind.nc.k1ll3d.tmp").write_bytes(b"\x89HDF\r\n\x1a\n partial")

    monkeypatch.setenv("CWPROC_TOY_JOURNAL", str(journal))
    report = run_toy(inputs, out)
    assert report.ok
    assert report.stale_lock.startswith(f"pid={proc.pid} ")
    assert report.units_up_to_date == len(done_before)
    assert leftovers(out) == []
    assert len(assert_products_open(out)) == 8
    assert len(load_ledger(out / STATE_DIR / "ledger.json").units) == 8
    runs = journal.read_text().split()
    counts = {key: runs.count(key) for key in set(runs)}
    assert len(counts) == 8
    assert all(counts[key] == 1 for key in done_before)
    # at most the unit in flight at the kill was done twice
    assert sum(counts.values()) <= 9


def test_concurrent_run_gives_up_or_waits_and_then_finds_nothing_to_do(tmp_path):
    inputs, out, journal = tmp_path / "in", tmp_path / "out", tmp_path / "journal"
    day_archive(inputs, 4)
    proc = start_toy_run(inputs, out, journal, sleep_s=0.3)
    try:
        lock = out / STATE_DIR / "lock"
        wait_for(lambda: lock.exists() and f"pid={proc.pid}" in lock.read_text(), proc)
        with pytest.raises(LockBusyError, match=f"pid={proc.pid}"):
            run_toy(inputs, out)
        waited = run_toy(inputs, out, wait_s=24 * 3600.0)  # until the lock is released
        stdout, stderr = proc.communicate()  # the run ends by itself
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 0, stderr
    assert stdout.strip() == "done 4"
    assert waited.ok and waited.processed == [] and waited.units_up_to_date == 4
    assert sorted(journal.read_text().split()) == [f"toy_K_202402{d:02d}" for d in range(1, 5)]


# --------------------------------------------------------------------------------------
# bad inputs and write errors
# --------------------------------------------------------------------------------------


def test_corrupted_input_fails_alone_with_file_and_line_and_is_retried(tmp_path):
    inputs, out = tmp_path / "in", tmp_path / "out"
    paths = toy_archive(inputs, n_days=3)
    bad = paths[3]  # second file of day 2
    lines = bad.read_text().splitlines()
    lines[4] = "12.5e"  # line 5 of the file
    bad.write_text("\n".join(lines) + "\n")

    first = run_toy(inputs, out)
    assert not first.ok
    assert [f.error for f in first.file_failures] == [f"{bad}:5: not a number: '12.5e'"]
    assert first.failure_lines() == [f"{bad}:5: not a number: '12.5e'"]
    assert len(first.succeeded) == 3  # day 2 made from its good file, like retrieve
    ledger = load_ledger(out / STATE_DIR / "ledger.json")
    assert ledger.failures[os.fspath(bad)]["attempts"] == 1

    second = run_toy(inputs, out)
    assert [f.path for f in second.file_failures] == [os.fspath(bad)]
    assert second.processed == []
    ledger = load_ledger(out / STATE_DIR / "ledger.json")
    assert ledger.failures[os.fspath(bad)]["attempts"] == 2

    lines[4] = "12.5"
    bad.write_text("\n".join(lines) + "\n")
    third = run_toy(inputs, out)
    assert third.ok and [o.key for o in third.processed] == ["toy_A_20240102"]
    product = read_product(out / "toy_A_20240102_wind.nc")
    expected = np.concatenate([read_toy(str(p))["value"].values for p in paths[2:4]]).mean()
    np.testing.assert_allclose(product["wind_speed"].values, expected, rtol=1e-12)
    assert load_ledger(out / STATE_DIR / "ledger.json").failures == {}


def test_directory_in_place_of_a_product_fails_that_unit_only(tmp_path):
    inputs, out = tmp_path / "in", tmp_path / "out"
    toy_archive(inputs, n_days=3)
    blocker = out / "toy_A_20240102_wind.nc"
    blocker.mkdir(parents=True)  # root can write anywhere, but not a file onto a folder
    report = run_toy(inputs, out)
    assert [o.key for o in report.failed] == ["toy_A_20240102"]
    (line,) = report.failure_lines()
    assert line.startswith(f"{blocker}: cannot write product: ")
    ledger = load_ledger(out / STATE_DIR / "ledger.json")
    assert "toy_A_20240102" not in ledger.units
    assert ledger.failures["toy_A_20240102"]["error"] == line
    assert leftovers(out) == []
    blocker.rmdir()
    retry = run_toy(inputs, out)
    assert retry.ok and [o.key for o in retry.processed] == ["toy_A_20240102"]


def test_disk_full_gives_a_clear_message_and_no_ledger_entry(tmp_path, monkeypatch):
    inputs, out = tmp_path / "in", tmp_path / "out"
    toy_archive(inputs, n_days=2)

    def disk_full(self, path, *args, **kwargs):
        Path(path).write_bytes(b"\x89HDF\r\n\x1a\n half")
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(xr.Dataset, "to_netcdf", disk_full)
    report = run_toy(inputs, out)
    assert len(report.failed) == 2 and report.succeeded == []
    assert all(
        line.endswith("cannot write product: No space left on device")
        for line in report.failure_lines()
    )
    assert load_ledger(out / STATE_DIR / "ledger.json").units == {}
    assert list(out.glob("*.nc")) == [] and leftovers(out) == []


# --------------------------------------------------------------------------------------
# serial, --workers 2 and --scheduler give identical products
# --------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def workers_client():
    """The client ``--workers 2`` makes (a LocalCluster of 2 single-threaded processes),
    started once for the module; its scheduler address serves the ``--scheduler`` path.
    """
    pytest.importorskip("dask.distributed")
    client = dask_client(workers=2)
    yield client
    close_client(client)


def comparable(path: Path) -> xr.Dataset:
    ds = read_product(path)
    ds.attrs = {k: v for k, v in ds.attrs.items() if k not in DATE_ATTRS}
    return ds


def assert_same_products(a: Path, b: Path) -> None:
    names_a = sorted(p.name for p in a.glob("*.nc"))
    assert names_a and names_a == sorted(p.name for p in b.glob("*.nc"))
    for name in names_a:
        da, db = comparable(a / name), comparable(b / name)
        xr.testing.assert_identical(da, db)
        assert da.attrs == db.attrs


def run_ways(inputs: Path, tmp_path: Path, workers_client, **kw) -> dict[str, Path]:
    """Process ``inputs`` serially, on the ``--workers 2`` cluster, and through a second
    client connected to that cluster's scheduler address (the ``--scheduler`` path)."""
    outs = {k: tmp_path / k for k in ("serial", "workers", "scheduler")}
    reports = {
        "serial": run_batch(inputs, outs["serial"], **kw),
        "workers": run_batch(inputs, outs["workers"], client=workers_client, **kw),
    }
    address = workers_client.scheduler.address
    remote = dask_client(scheduler=address)
    try:
        reports["scheduler"] = run_batch(inputs, outs["scheduler"], client=remote, **kw)
    finally:
        remote.close()
    worker_pids = set(workers_client.run(os.getpid).values())
    for way, report in reports.items():
        assert report.ok, (way, report.failure_lines())
        pids = {o.pid for o in report.processed}
        # the units really ran in this process, or on the cluster's worker processes
        assert pids == ({os.getpid()} if way == "serial" else pids & worker_pids)
        assert pids
    return outs


@pytest.mark.slow
@pytest.mark.skipif(
    bool(_missing_pipeline_modules()),
    reason=f"pipeline modules not built yet: {', '.join(_missing_pipeline_modules())}",
)
def test_serial_workers_and_scheduler_give_identical_real_products(tmp_path, workers_client):
    from cwproc.io.halo import write_hpl

    inputs = tmp_path / "in"
    inputs.mkdir()
    for day, (u, v) in {"2024-05-01": (2.0, 7.0), "2024-05-02": (-5.0, -1.0)}.items():
        for hour in (0, 1):
            name = f"VAD_99_{day.replace('-', '')}_{hour:02d}0000.hpl"
            write_hpl(synthetic_vad_scans(day, hour, u, v), inputs / name)
    outs = run_ways(inputs, tmp_path, workers_client, config=wind_only_config())
    assert_same_products(outs["serial"], outs["workers"])
    assert_same_products(outs["serial"], outs["scheduler"])
    shutil.rmtree(inputs)


@pytest.mark.slow
@pytest.mark.skipif(
    bool(_missing_pipeline_modules()),
    reason=f"pipeline modules not built yet: {', '.join(_missing_pipeline_modules())}",
)
def test_kill_9_of_the_real_cli_then_rerun_rewrites_nothing_already_done(tmp_path):
    from cwproc.io.halo import write_hpl

    inputs, out = tmp_path / "in", tmp_path / "out"
    inputs.mkdir()
    n_days = 8
    for d in range(n_days):
        day = f"2024-07-{d + 1:02d}"
        scans = synthetic_vad_scans(day, 6, 1.0 + d, -2.0)
        write_hpl(scans, inputs / f"VAD_99_{day.replace('-', '')}_060000.hpl")
    config = tmp_path / "wind.toml"
    config.write_text("[turbulence]\nenabled = false\n")
    cmd = [sys.executable, "-m", "cwproc", "batch", str(inputs), str(out), "-c", str(config)]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        wait_for(lambda: len(ledger_units(out)) >= 1 or proc.poll() is not None, proc)
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    done = ledger_units(out)
    if proc.returncode != -signal.SIGKILL or len(done) == n_days:
        pytest.fail("the run finished before it could be killed; make the archive larger")
    stamps = {key: os.stat(rec["products"][0]).st_mtime_ns for key, rec in done.items()}

    rerun = run_batch(inputs, out, load_config(config))  # what the CLI calls
    assert rerun.ok, rerun.failure_lines()
    assert rerun.units_up_to_date == len(done)
    assert rerun.stale_lock.startswith(f"pid={proc.pid} ")
    assert leftovers(out) == []
    assert len(assert_products_open(out)) == n_days
    final = ledger_units(out)
    assert len(final) == n_days
    for key, stamp in stamps.items():  # done before the kill: not written again
        assert os.stat(final[key]["products"][0]).st_mtime_ns == stamp
    for d in range(n_days):  # each product holds its own day's wind
        wind = read_product(out / f"streamline_99_202407{d + 1:02d}_wind.nc")
        np.testing.assert_allclose(wind["u"].values, 1.0 + d, atol=0.01)
