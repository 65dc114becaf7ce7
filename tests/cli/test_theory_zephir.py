"""``cwproc theory zephir-ratio``."""

from __future__ import annotations

import pytest
from click.testing import CliRunner

from cwproc.cli import main
from cwproc.physics.volume_averaging import std_ratio_and_tp_share


def _run(*args: str):
    return CliRunner().invoke(main, ["theory", "zephir-ratio", *args])


def test_table_values_match_the_model():
    result = _run("--heights", "40,100", "--wind-speed", "8", "--scan-time", "3")
    assert result.exit_code == 0, result.output
    rows = [line.split() for line in result.output.splitlines() if line.strip()[:1].isdigit()]
    assert [float(r[0]) for r in rows] == [40.0, 100.0]
    for row in rows:
        h = float(row[0])
        ratio, share = std_ratio_and_tp_share(h, 8.0, 3.0)
        assert float(row[1]) == pytest.approx(h / 0.8660254, abs=0.06)  # R = h / cos 30
        assert float(row[3]) == pytest.approx(2 * h * 0.5773503 + 24.0, abs=0.06)  # l_az
        assert float(row[4]) == pytest.approx(ratio, abs=6e-4)
        assert float(row[5]) == pytest.approx(share, abs=6e-4)


def test_both_scan_times_by_default_with_1s_above_3s():
    result = _run("--heights", "60 80")
    assert result.exit_code == 0, result.output
    assert "ratio 1s" in result.output and "ratio 3s" in result.output
    for line in result.output.splitlines():
        if line.strip()[:1].isdigit():
            cells = [float(c) for c in line.split()]
            assert cells[4] > cells[7]  # ratio 1 s > ratio 3 s (Wagner et al. (DTU), 5.1)


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (("--heights", "40,abc"), "not a list of numbers"),
        (("--heights", "-5"), "heights > 0"),
        (("--wind-speed", "0"), "must be > 0"),
        (("--scan-time", "2"), "'2' is not one of"),
    ],
)
def test_bad_options_are_usage_errors(args, words):
    result = _run(*args)
    assert result.exit_code == 2
    assert words in result.output
