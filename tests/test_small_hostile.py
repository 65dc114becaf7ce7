"""Small hostile-input cases of issue 17.9: each a clear one-line answer, no hang."""

import os
import threading
from pathlib import Path

import pytest
from click.testing import CliRunner

from cwproc.cli import main
from cwproc.config import config_from_toml, load_config
from cwproc.errors import ConfigError, InputFileError, one_line

SAMPLE = Path(__file__).resolve().parents[1] / "sample_data"


def test_fifo_on_the_command_line_is_refused_without_hanging(tmp_path):
    fifo = tmp_path / "pipe.hpl"
    os.mkfifo(fifo)
    result: dict = {}

    def run() -> None:
        result["r"] = CliRunner().invoke(main, ["retrieve", str(fifo), "-o", str(tmp_path / "o")])

    worker = threading.Thread(target=run, daemon=True)
    worker.start()
    worker.join(timeout=30)
    assert not worker.is_alive(), "retrieve hung on a FIFO"
    assert result["r"].exit_code == 1
    assert "not a regular file" in result["r"].output


def test_error_lines_stay_short():
    """A CR-only file is one 'line': its quote is cut, control characters shown."""
    err = InputFileError("x.sta", "bad line " + "a\rb" * 50_000, 3)
    text = str(err)
    assert "\r" not in text and "\n" not in text
    assert len(text) < 400
    assert one_line("short") == "short"


def test_reader_table_in_the_wrong_case_is_an_error():
    with pytest.raises(ConfigError, match=r"did you mean \[reader\.meteo2\]"):
        config_from_toml('[reader.Meteo2]\ndelimiter = ","')
    assert config_from_toml('[reader.meteo2]\ndelimiter = ","').reader == {
        "meteo2": {"delimiter": ","}
    }


def test_config_with_a_byte_order_mark_loads(tmp_path):
    path = tmp_path / "site.toml"
    path.write_bytes(b"\xef\xbb\xbf[qc]\nsnr_min = 0.01\n")
    assert load_config(path).qc.snr_min == 0.01


@pytest.mark.parametrize("key", ["latitude", "longitude"])
def test_half_a_position_is_an_error(key):
    with pytest.raises(ConfigError, match=r"set (latitude|longitude) too"):
        config_from_toml(f"[output]\n{key} = 45.0\n")
