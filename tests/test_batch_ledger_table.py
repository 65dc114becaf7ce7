"""The ledger's file table held compactly (issue 35, driver memory): one slotted
record a file with interned strings, shared with the plan; the snapshot written in
chunks with the bytes of one ``json.dumps``; loads and journals give the same records."""

from __future__ import annotations

import dataclasses
import json
import tracemalloc

import cwproc.batch.state as state
from cwproc.batch import FileInfo, Ledger, cached_file_info, load_ledger, record_file, save_ledger
from cwproc.batch.state import FILE_FIELDS, FileTable

CFG = "c" * 64


def day_infos(day: int, n: int, sha: bool = False) -> list[FileInfo]:
    """``n`` classified files of one day, each unit and hash a fresh string object (as
    records unpickled from workers are)."""
    return [
        FileInfo(
            f"/archive/2024/01/{day:02d}/VAD_999_202401{day:02d}_{k:06d}.hpl",
            630_000 + k,
            1_700_000_000_000_000_000 + k,
            "".join(["o", "k"]),
            sha256=f"{k:064x}" if sha else "",
            format="hpl",
            kind="scan",
            unit="".join(["streamline_999_202401", f"{day:02d}"]),
            start=f"2024-01-{day:02d}T00:00:{k % 60:02d}Z",
            config_hash="".join([CFG]),
        )
        for k in range(n)
    ]


def test_entries_are_the_records_the_plan_holds_with_shared_strings():
    ledger = Ledger()
    infos = day_infos(1, 5)
    kept = [record_file(ledger, info) for info in infos]
    assert all(ledger.files.record(i.path) is k for i, k in zip(infos, kept, strict=True))
    assert kept[0].unit is kept[4].unit and kept[0].config_hash is kept[4].config_hash
    assert infos[0].unit is not infos[4].unit  # the inputs did not share them
    assert ledger.files[infos[2].path] == dataclasses.asdict(infos[2])
    assert set(ledger.files.changed) == {i.path for i in infos}
    info = infos[3]
    found = cached_file_info(ledger, info.path, info.size, info.mtime_ns, CFG)
    assert found is kept[3]  # no copy made for the plan
    assert cached_file_info(ledger, info.path, info.size + 1, info.mtime_ns, CFG) is None


def test_snapshot_in_chunks_is_one_json_dumps_and_loads_back(tmp_path, monkeypatch):
    monkeypatch.setattr(state, "SNAPSHOT_CHUNK", 3)
    ledger = Ledger()
    for info in day_infos(1, 7, sha=True) + day_infos(2, 4):
        record_file(ledger, info)
    ledger.files["/old/entry"] = {"size": 5}  # another version's entry: kept as given
    ledger.units["u"] = {"fingerprint": "f", "inputs": {"/a": "b"}, "products": []}
    ledger.failures["/x"] = {"error": "bad", "attempts": 1}
    doc = {
        "version": 1,
        "files": {k: ledger.files[k] for k in ledger.files},
        "units": dict(ledger.units),
        "failures": dict(ledger.failures),
    }
    assert ledger.to_json() == json.dumps(doc, separators=(",", ":"))
    save_ledger(ledger, tmp_path / "ledger.json")
    assert (tmp_path / "ledger.json").read_text() == ledger.to_json()
    again = load_ledger(tmp_path / "ledger.json")
    assert json.loads(again.to_json()) == doc
    records = [again.files.record(k) for k in again.files]
    assert isinstance(again.files.record("/old/entry"), dict)
    files = [r for r in records if isinstance(r, FileInfo)]
    assert len(files) == 11
    assert files[0].config_hash is files[-1].config_hash and files[0].unit is files[6].unit


def test_journalled_file_entries_load_as_records(tmp_path):
    path = tmp_path / "ledger.json"
    ledger = Ledger()
    record_file(ledger, day_infos(1, 1)[0])
    save_ledger(ledger, path)  # the snapshot
    later = day_infos(3, 3)
    for info in later:
        record_file(ledger, info)
    del ledger.files[day_infos(1, 1)[0].path]
    save_ledger(ledger, path)  # journalled
    assert path.with_name("ledger.json.journal").exists()
    again = load_ledger(path)
    assert list(again.files) == [i.path for i in later]
    assert all(again.files.record(i.path) == i for i in later)
    assert again.files.record(later[0].path).unit is again.files.record(later[2].path).unit
    assert not again.files.changed


def traced_growth(build) -> tuple[object, int]:
    """What ``build()`` returns, and the bytes it left allocated."""
    tracemalloc.start()
    try:
        before = tracemalloc.get_traced_memory()[0]
        kept = build()
        return kept, tracemalloc.get_traced_memory()[0] - before
    finally:
        tracemalloc.stop()


def test_a_file_entry_costs_the_driver_well_under_a_dict():
    """What the table adds to the plan's records: under 250 bytes a file (a year's
    700,800 files in 170 MiB); a dict a file, as the ledger held them, 2.5 times that
    at least (480 bytes; 650 as ``dataclasses.asdict`` grew them)."""
    n = 20_000
    infos = [i for day in range(1, 5) for i in day_infos(day, n // 4)]

    def table() -> FileTable:
        built = FileTable()
        for info in infos:
            built.put(info)
        built.changed.clear()
        return built

    def dicts() -> dict:
        return {i.path: {f: getattr(i, f) for f in FILE_FIELDS} for i in infos}

    kept, compact = traced_growth(table)
    assert len(kept) == n
    kept, plain = traced_growth(dicts)
    assert len(kept) == n
    assert compact / n < 250, f"{compact / n:.0f} bytes a file"
    assert compact < plain / 2.5, (compact / n, plain / n)
