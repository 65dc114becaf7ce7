"""The distributed run (issue 35.3): a ``dask.distributed`` LocalCluster and a process
pool give the products of the serial run; a task the cluster could not run (an
exception, a worker killed) is retried within the run; the ledger is written by the
driver alone.

Toy backend of ``test_batch.py`` (the functions are shipped to the workers by
reference: this folder is on their ``sys.path``).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest

import cwproc.batch.run as batch_run
import cwproc.batch.state as batch_state
from cwproc.batch import (
    STATE_DIR,
    UnitOutcome,
    UnitTask,
    close_client,
    dask_client,
    load_ledger,
    local_pool,
    run_tasks,
)

sys.path.insert(0, str(Path(__file__).resolve().parent))

from test_batch import run_toy, toy_archive, toy_classify, toy_process
from test_batch_faults import assert_same_products


def flaky_process(task: UnitTask) -> UnitOutcome:
    """``toy_process``, but the first attempt at each unit fails: it raises, or (unit
    keys ending in an even digit, when the file ``marks/kill`` exists) kills its worker
    process, as a lost node or an out-of-memory kill would. The marks are files in
    ``marks/`` beside the output folder, so that attempts in other processes, and in a
    worker restarted after a kill, count."""
    marks = Path(task.outdir).parent / "marks"
    mark = marks / task.key
    if not mark.exists():
        mark.touch()
        if int(task.key[-1]) % 2 == 0 and (marks / "kill").exists():
            os._exit(17)  # the worker process dies mid-task
        raise OSError(f"{task.key}: node lost (first attempt)")
    return toy_process(task)


def double(x: int) -> int:
    return 2 * x


def fails_once(x: int, folder: str) -> int:
    mark = Path(folder) / str(x)
    if not mark.exists():
        mark.touch()
        raise RuntimeError(f"{x}: first attempt")
    return 2 * x


@pytest.fixture(scope="module")
def cluster():
    """A LocalCluster of 2 single-threaded worker processes (``--workers 2`` with Dask)."""
    pytest.importorskip("dask.distributed")
    client = dask_client(workers=2)
    yield client
    close_client(client)


@pytest.mark.parametrize("way", ["pool", "dask"])
def test_run_tasks_retries_a_task_that_raised(tmp_path, way, request):
    client = local_pool(2) if way == "pool" else request.getfixturevalue("cluster")
    try:
        got = dict(run_tasks(fails_once, [1, 2, 3], str(tmp_path), client=client, retries=1))
        assert got == {1: 2, 2: 4, 3: 6}
        (tmp_path / "again").mkdir()
        got = dict(run_tasks(fails_once, [1, 2], str(tmp_path / "again"), client=client, retries=0))
        assert all(isinstance(r, RuntimeError) for r in got.values())
        assert dict(run_tasks(double, [5], client=client)) == {5: 10}
    finally:
        if way == "pool":
            close_client(client)


def test_local_cluster_retries_failed_units_and_matches_the_serial_run(
    tmp_path, cluster, monkeypatch
):
    inputs = tmp_path / "in"
    toy_archive(inputs, n_days=4, files_per_day=3)
    serial = run_toy(inputs, tmp_path / "serial")
    assert serial.ok and len(serial.succeeded) == 4

    marks = tmp_path / "marks"
    marks.mkdir()
    (marks / "kill").touch()
    saves: list[int] = []
    original = batch_state.save_ledger

    def recording(ledger, path, **kw):
        saves.append(os.getpid())
        return original(ledger, path, **kw)

    monkeypatch.setattr(batch_run, "save_ledger", recording)
    report = batch_run.run_batch(
        inputs,
        tmp_path / "cluster",
        batch_run.Config(),
        client=cluster,
        classify=toy_classify,
        process=flaky_process,
    )
    assert report.ok, report.failure_lines()
    assert len(report.succeeded) == 4
    tried = sorted(p.name for p in marks.iterdir() if p.name != "kill")
    assert tried == sorted(o.key for o in report.succeeded)
    assert {o.pid for o in report.processed} - {os.getpid()}  # ran on the workers
    assert set(saves) == {os.getpid()}  # the ledger: the driver alone
    ledger = load_ledger(tmp_path / "cluster" / STATE_DIR / "ledger.json")
    assert set(ledger.units) == {o.key for o in report.succeeded} and not ledger.failures
    assert_same_products(tmp_path / "serial", tmp_path / "cluster")


def test_without_retries_a_failed_unit_is_recorded_and_redone_by_the_next_run(
    tmp_path, cluster, monkeypatch
):
    inputs = tmp_path / "in"
    toy_archive(inputs, n_days=2, files_per_day=2)
    (tmp_path / "marks").mkdir()
    monkeypatch.setattr(batch_run, "TASK_RETRIES", 0)

    def run():
        return batch_run.run_batch(
            inputs,
            tmp_path / "out",
            batch_run.Config(),
            client=cluster,
            classify=toy_classify,
            process=flaky_process,
        )

    first = run()
    assert len(first.failed) == 2 and not first.ok
    assert all("the cluster could not run it: OSError" in o.error for o in first.failed)
    ledger = load_ledger(tmp_path / "out" / STATE_DIR / "ledger.json")
    assert ledger.units == {} and len(ledger.failures) == 2
    second = run()
    assert second.ok and len(second.succeeded) == 2
    run_toy(inputs, tmp_path / "serial")
    assert_same_products(tmp_path / "serial", tmp_path / "out")
