"""Background files beside .hpl files: used by retrieve and batch, described by info."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from cwproc.cli import main

REPO = Path(__file__).resolve().parents[2]
SAMPLES = REPO / "sample_data" / "streamline"  # 2 VAD files of 2024-06-01 12:00, 24 gates


@pytest.fixture()
def folder(tmp_path):
    data = tmp_path / "in"
    data.mkdir()
    for p in SAMPLES.glob("*.hpl"):
        shutil.copy(p, data)
    return data


def _good_background(folder: Path, name: str = "Background_010624-115958.txt") -> Path:
    values = 1.7e7 * (1.0 + 1e-5 * (np.arange(40) + 0.5) * 30.0)
    path = folder / name
    path.write_bytes("".join(f"{v:.6f}\r\n" for v in values).encode())
    return path


def run(*args):
    return CliRunner().invoke(main, [*map(str, args)])


def test_retrieve_corrects_snr_with_the_background_beside_the_files(folder, tmp_path):
    _good_background(folder)
    res = run("retrieve", folder, "-o", tmp_path / "out")
    assert res.exit_code == 0, res.output
    assert "SNR of 2160 of 2160 rays corrected with 1 background file(s)" in res.output
    assert "Background_010624-115958.txt: Stream Line background file" in res.output
    names = sorted(p.name for p in (tmp_path / "out").glob("*.nc"))
    assert names == ["streamline_999_20240601_turbulence.nc", "streamline_999_20240601_wind.nc"]


def test_damaged_background_gives_a_note_and_the_products(folder, tmp_path):
    bad = folder / "Background_010624-115958.txt"
    bad.write_bytes(b"16800000.125000\r\n1680x000.5\r\n16800000.5\r\n")
    res = run("retrieve", folder, "-o", tmp_path / "out")
    assert res.exit_code == 0, res.output
    assert "Traceback" not in res.output
    assert f"background file not used: {bad}:2: expected one background value" in res.output
    assert "SNR not corrected: none of 2160 rays" in res.output
    assert len(list((tmp_path / "out").glob("*.nc"))) == 2


def test_no_background_no_note_and_the_same_products(folder, tmp_path):
    res = run("retrieve", folder, "-o", tmp_path / "out")
    assert res.exit_code == 0, res.output
    assert "SNR" not in res.output
    assert len(list((tmp_path / "out").glob("*.nc"))) == 2


def test_switched_off_and_configured_folder(folder, tmp_path):
    elsewhere = tmp_path / "backgrounds"
    elsewhere.mkdir()
    _good_background(elsewhere)
    off = tmp_path / "off.toml"
    off.write_text(f'[background]\nenabled = false\nfolder = "{elsewhere}"\n')
    res = run("retrieve", folder, "-c", off, "-o", tmp_path / "a")
    assert res.exit_code == 0 and "SNR" not in res.output, res.output
    on = tmp_path / "on.toml"
    on.write_text(f'[background]\nfolder = "{elsewhere}"\n')
    res = run("retrieve", folder, "-c", on, "-o", tmp_path / "b")
    assert res.exit_code == 0, res.output
    assert "SNR of 2160 of 2160 rays corrected" in res.output


def test_batch_skips_background_files_as_inputs(folder, tmp_path):
    _good_background(folder)
    res = run("batch", folder, tmp_path / "out", "-v")
    assert res.exit_code == 0, res.output
    assert "Background_010624-115958.txt: a Stream Line background file" in res.output
    assert len(list((tmp_path / "out").glob("*.nc"))) == 2


def test_info_describes_a_background_file(tmp_path):
    path = _good_background(tmp_path)
    res = run("info", path)
    assert res.exit_code == 0, res.output
    assert "halo_background (Halo Photonics Stream Line background profile)" in res.output
    assert "time          2024-06-01T11:59:58.000Z" in res.output
    assert "gates         40 (lines layout)" in res.output
