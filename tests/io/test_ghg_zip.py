"""LI-COR .ghg archives: the .data member read safely (issue 17.9)."""

import zipfile
from pathlib import Path

import pytest

from cwproc.errors import InputFileError
from cwproc.io import Format, detect_format, read_file
from cwproc.io.licor import read_ghg

SAMPLE = Path(__file__).resolve().parents[2] / "sample_data" / "sonic"
DATA = next(SAMPLE.glob("*.data"))


def archive(tmp_path: Path, members: dict[str, bytes]) -> Path:
    path = tmp_path / "2024-06-01T120000_AIU-0999.ghg"
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as zf:
        for name, data in members.items():
            zf.writestr(name, data)
    return path


def test_ghg_archive_reads_like_its_data_file(tmp_path):
    raw = DATA.read_bytes()
    path = archive(tmp_path, {"x.metadata": b"[Site]\n", DATA.name: raw})
    assert detect_format(path) is Format.GHG
    from_zip, plain = read_file(path), read_ghg(DATA)
    assert from_zip.sizes == plain.sizes
    assert (from_zip["u"].values[:100] == plain["u"].values[:100]).all()


@pytest.mark.parametrize(
    ("members", "problem"),
    [
        ({"a.metadata": b"x"}, "one .data file"),
        ({"a.data": b"Model: x\n", "b.data": b"Model: y\n"}, "one .data file"),
        ({"../../evil.data": b"Model: x\n\x00"}, "NUL"),
    ],
)
def test_bad_archives_are_clear_errors(tmp_path, members, problem):
    with pytest.raises(InputFileError, match=problem):
        read_ghg(archive(tmp_path, members))
    assert not (tmp_path.parent / "evil.data").exists()


def test_zip_bomb_is_refused(tmp_path):
    path = archive(tmp_path, {"a.data": b"Model: x\n" + b"0" * 5_000_000})
    with pytest.raises(InputFileError, match="implausible"):
        read_ghg(path)
