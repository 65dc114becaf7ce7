"""``write_bytes_atomic``: the one way cwproc writes a small file (simulated files, truth
JSON, sf-type tables) -- whole or not at all, never through a planted symlink, with the
umask's mode, and no temporary left behind (issue 17.6)."""

from __future__ import annotations

import os
import stat

import pytest

from cwproc.io.netcdf import remove_stale_temporaries, write_bytes_atomic


def test_whole_file_with_the_umask_mode(tmp_path):
    old = os.umask(0o027)
    try:
        path = write_bytes_atomic(tmp_path / "truth.json", b'{"epsilon": 0.01}\n')
    finally:
        os.umask(old)
    assert path.read_bytes() == b'{"epsilon": 0.01}\n'
    assert stat.S_IMODE(path.stat().st_mode) == 0o640
    assert [p.name for p in tmp_path.iterdir()] == ["truth.json"]


def test_a_planted_symlink_is_replaced_not_followed(tmp_path):
    victim = tmp_path / "victim.txt"
    victim.write_text("user data")
    link = tmp_path / "sf_parameters.csv"
    link.symlink_to(victim)
    write_bytes_atomic(link, b"type,count\n")
    assert victim.read_text() == "user data"
    assert not link.is_symlink() and link.read_bytes() == b"type,count\n"


def test_a_failed_write_leaves_neither_file_nor_temporary(tmp_path, monkeypatch):
    def fail(*args, **kwargs):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "replace", fail)
    with pytest.raises(OSError, match="No space left"):
        write_bytes_atomic(tmp_path / "sf_type_occurrence.csv", b"x" * 1000)
    assert list(tmp_path.iterdir()) == []


def test_temporaries_of_a_killed_writer_are_removed_when_stale(tmp_path):
    for name in (".truth.json.abc123.tmp", ".sf_parameters.csv.x9.tmp"):
        stale = tmp_path / name
        stale.write_bytes(b"half")
        os.utime(stale, (0, 0))
    fresh = tmp_path / ".other.csv.live.tmp"  # a live run's: too young to remove
    fresh.write_bytes(b"live")
    removed = remove_stale_temporaries(tmp_path)
    assert sorted(p.name for p in removed) == [
        ".sf_parameters.csv.x9.tmp",
        ".truth.json.abc123.tmp",
    ]
    assert fresh.exists()
