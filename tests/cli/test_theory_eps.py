"""``cwproc theory eps-ratio``: the table of Smalikho (2020), eq. 21 and its plot."""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner

from cwproc.cli.theory_eps import DEFAULT_LAG, eps_ratio_command, first_exceedance


def _table(output: str) -> np.ndarray:
    rows = [line.split() for line in output.splitlines() if line and line[0] == " "]
    return np.array([[float(v) for v in row] for row in rows if row[0] != "mu"])


def test_default_table_reproduces_reference_row():
    result = CliRunner().invoke(eps_ratio_command, ["--phi", "60", "--dy", "3", "--mu-step", "0.5"])
    assert result.exit_code == 0, result.output
    table = _table(result.output)
    # REFERENCE_VALUES.md 1.3.pi, phi = 60, dy = 3, l = 3 (the default lag)
    assert DEFAULT_LAG == 3
    expected = {0.0: 1.0, 0.5: 1.0888, 1.0: 1.4348, 1.5: 2.1947, 2.0: 3.2284, 3.0: 5.7107}
    for mu, ratio in expected.items():
        row = table[np.isclose(table[:, 0], mu)][0]
        assert row[1] == pytest.approx(ratio, abs=2e-4)
    # asymptote columns: q1(60) mu and q2(60) mu^2.5 (Smalikho (2020), eqs. 22-23)
    row = table[np.isclose(table[:, 0], 2.0)][0]
    assert row[2] == pytest.approx((0.75 + 7 / 32) ** 1.5 * 2, abs=1e-4)
    assert row[3] == pytest.approx((0.75 + 1 / 8) ** 1.5 * 2**2.5, abs=1e-4)
    assert "first exceeds 1.1 at mu = 0.529" in result.output


def test_printed_transfer_and_lag_option():
    result = CliRunner().invoke(
        eps_ratio_command,
        ["--phi", "16", "--dy", "12", "--lag", "2", "--transfer", "printed", "--mu-max", "2"],
    )
    assert result.exit_code == 0, result.output
    table = _table(result.output)
    # REFERENCE_VALUES.md 1.3.2, phi = 16, dy = 12: mu = 1 -> 1.0124, mu = 2 -> 1.8632
    assert table[np.isclose(table[:, 0], 1.0)][0, 1] == pytest.approx(1.0124, abs=2e-4)
    assert table[np.isclose(table[:, 0], 2.0)][0, 1] == pytest.approx(1.8632, abs=2e-4)


def test_png_is_written(tmp_path):
    png = tmp_path / "ratio.png"
    result = CliRunner().invoke(
        eps_ratio_command, ["--phi", "45", "--dy", "6", "--mu-max", "2", "--png", str(png)]
    )
    assert result.exit_code == 0, result.output
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_unwritable_png_is_one_line_error(tmp_path):
    target = tmp_path / "missing-dir" / "x.png"
    result = CliRunner().invoke(
        eps_ratio_command, ["--phi", "45", "--mu-max", "1", "--png", str(target)]
    )
    assert result.exit_code == 1
    assert "cannot write" in result.output
    assert "Traceback" not in result.output


@pytest.mark.parametrize(
    "args",
    [["--dy", "3"], ["--phi", "95"], ["--phi", "60", "--lag", "1"], ["--phi", "60", "--dy", "0"]],
)
def test_bad_arguments_are_usage_errors(args):
    result = CliRunner().invoke(eps_ratio_command, args)
    assert result.exit_code == 2
    assert "Traceback" not in result.output


def test_first_exceedance_interpolates():
    mu = np.array([0.0, 1.0, 2.0])
    assert first_exceedance(mu, np.array([1.0, 1.0, 1.2])) == pytest.approx(1.5)
    assert np.isnan(first_exceedance(mu, np.array([1.0, 1.05, 1.09])))
