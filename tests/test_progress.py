"""Progress: bars on a terminal only, and only where a command turned them on."""

from __future__ import annotations

import io

from cwproc import progress


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_shown_on_a_terminal_unless_quiet():
    assert progress.shown_on(quiet=False, stream=_Terminal())
    assert not progress.shown_on(quiet=True, stream=_Terminal())
    assert not progress.shown_on(quiet=False, stream=io.StringIO())  # cron: a file or pipe


def test_off_by_default_track_returns_the_iterable_itself():
    items = [1, 2, 3]
    assert not progress.is_on()
    assert progress.track(items, desc="x") is items
    with progress.bar(desc="x", total=3) as handle:
        handle.update(3)  # the silent stand-in accepts the calls


def test_on_inside_reporting_only(monkeypatch):
    stream = _Terminal()
    monkeypatch.setattr(progress, "DELAY_S", 0.0)
    monkeypatch.setattr("sys.stderr", stream)
    with progress.reporting(True):
        assert progress.is_on()
        assert sum(progress.track(range(5), desc="adding")) == 10
        with progress.bar(desc="by hand", total=2) as handle:
            handle.update(2)
    assert not progress.is_on()
    assert "adding" in stream.getvalue() and "by hand" in stream.getvalue()
