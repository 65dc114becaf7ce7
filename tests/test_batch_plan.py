"""Planning that scales (issue 35.1): classification in batches of files, each ``.hpl``
file read once in a first run, its checksum taken from the bytes its unit parses."""

from __future__ import annotations

import os
import shutil
import sys
from collections import Counter
from pathlib import Path

import pytest

import cwproc.batch.run as batch_run
import cwproc.io.netcdf as netcdf
import cwproc.pipeline.input_files as input_files
from cwproc.batch import STATE_DIR, load_ledger, plan_units, process_unit_task, run_batch
from cwproc.batch.run import (
    CLASSIFY_BATCH_FILES,
    _as_file_infos,
    classification_batches,
    classify_mode,
)
from cwproc.batch.worker import classify_batch, classify_file
from cwproc.config import Config
from cwproc.io.netcdf import sha256_file

sys.path.insert(0, str(Path(__file__).resolve().parent))

from test_batch import (
    run_toy,
    synthetic_vad_scans,
    toy_archive,
    wind_only_config,
)

REPO = Path(__file__).resolve().parents[1]
STREAMLINE = REPO / "sample_data" / "streamline"


def test_a_year_of_files_is_classified_in_a_few_hundred_tasks():
    year = [(f"/archive/{i // 1920:03d}/VAD_{i:07d}.hpl", "header") for i in range(365 * 1920)]
    batches = classification_batches(year)
    assert len(batches) == -(-len(year) // CLASSIFY_BATCH_FILES) == 351
    assert max(map(len, batches)) == CLASSIFY_BATCH_FILES
    assert [item for batch in batches for item in batch] == year  # consecutive, all


def test_a_small_archive_still_spreads_over_many_tasks():
    items = [(f"f{i:03d}", "header") for i in range(130)]
    batches = classification_batches(items, min_batches=64)
    assert len(batches) == 44 and {len(b) for b in batches} == {3, 1}
    assert classification_batches(items[:5], min_batches=64) == [(i,) for i in items[:5]]
    assert classification_batches([]) == []


def test_classify_mode_follows_the_ledger_entry():
    assert classify_mode(None) == "header"
    assert classify_mode({"status": "ok", "sha256": "ab"}) == "checksum"
    assert classify_mode({"status": "ok", "sha256": ""}) == "header"
    assert classify_mode({"status": "error", "sha256": ""}) == "whole"


def test_a_batch_lost_with_its_worker_fails_each_of_its_files(tmp_path):
    paths = [tmp_path / "a.hpl", tmp_path / "b.hpl"]
    for p in paths:
        p.write_text("x")
    infos = _as_file_infos([(os.fspath(p), "header") for p in paths], OSError("worker lost"))
    assert [i.status for i in infos] == ["error", "error"]
    assert [i.error for i in infos] == [
        f"{p}: could not be classified: OSError('worker lost')" for p in paths
    ]
    assert infos[0].size == 1


def test_run_batch_classifies_in_batches_not_one_task_per_file(tmp_path, monkeypatch):
    toy_archive(tmp_path / "in", n_days=10, files_per_day=13)  # 130 files
    tasks: Counter = Counter()
    original = batch_run.run_tasks

    def counting(fn, items, *args, **kw):
        tasks[fn.__name__] += len(items)
        return original(fn, items, *args, **kw)

    monkeypatch.setattr(batch_run, "run_tasks", counting)
    report = run_toy(tmp_path / "in", tmp_path / "out")
    assert report.ok and len(report.succeeded) == 10
    assert tasks == Counter(classify_batch=44, toy_process=10)


@pytest.fixture
def whole_checksums(monkeypatch) -> Counter:
    """Paths checksummed by a read of their own (``sha256_file``), not by the parse."""
    counts: Counter = Counter()
    original = netcdf.sha256_file

    def counting(path, *rest, **kw):
        counts[os.fspath(path)] += 1
        return original(path, *rest, **kw)

    monkeypatch.setattr(input_files, "sha256_file", counting)
    return counts


def test_first_run_takes_each_checksum_from_the_bytes_its_unit_parses(tmp_path, whole_checksums):
    inputs, out = tmp_path / "in", tmp_path / "out"
    shutil.copytree(STREAMLINE, inputs)
    paths = sorted(inputs.glob("*.hpl"))
    report = run_batch(inputs, out, Config())
    assert report.ok and len(report.succeeded) == 1
    assert whole_checksums == Counter()  # no read for a checksum alone
    ledger = load_ledger(out / STATE_DIR / "ledger.json")
    for path in paths:
        assert ledger.files[os.fspath(path)]["sha256"] == sha256_file(path)
    (record,) = ledger.units.values()
    assert record["inputs"] == {os.fspath(p): sha256_file(p) for p in paths}

    again = run_batch(inputs, out, Config())
    assert again.processed == [] and again.units_up_to_date == 1

    os.utime(paths[0], ns=(1, 1))  # touched, content unchanged: checksummed, not redone
    touched = run_batch(inputs, out, Config())
    assert touched.processed == [] and touched.units_up_to_date == 1
    assert whole_checksums == Counter({os.fspath(paths[0]): 1})


def test_new_file_changed_after_classification_fails_its_unit(tmp_path):
    from cwproc.io.halo import write_hpl

    path = tmp_path / "VAD_99_20240301_100000.hpl"
    write_hpl(synthetic_vad_scans("2024-03-01", 10, 1.0, 1.0), path)
    config = wind_only_config()
    (info,) = classify_batch([(os.fspath(path), "header")], classify_file, config.to_toml())
    assert info.status == "ok" and info.sha256 == ""
    ((task, _),) = plan_units([info], config, tmp_path / "out")
    assert task.fingerprint == "" and task.signatures == ((info.size, info.mtime_ns),)
    with path.open("ab") as fh:  # appended to meanwhile
        fh.write(b"\n")
    outcome = process_unit_task(task)
    assert outcome.error == (
        f"{path}: changed while the run was going on; "
        f"unit {task.key} will be redone by the next run"
    )
    assert not (tmp_path / "out").exists()


def test_a_unit_with_a_checksum_still_to_take_is_never_up_to_date(tmp_path):
    from cwproc.batch import BatchReport, FileInfo, Ledger
    from cwproc.batch.run import _units_to_do

    info = FileInfo("/a/VAD_1.hpl", 10, 1, "ok", format="hpl", kind="scan", unit="u")
    ((task, start),) = plan_units([info], Config(), tmp_path)
    assert task.fingerprint == ""
    ledger = Ledger()
    ledger.units["u"] = {"fingerprint": "", "products": []}  # as a unit recorded without it
    report = BatchReport()
    assert _units_to_do([(task, start)], ledger, None, report) == [task]
    assert report.units_up_to_date == 0
