"""The allocator is tuned only by the process's owner (issue 33): ``cwproc.memory``."""

from __future__ import annotations

import subprocess
import sys

import pytest

from cwproc import memory


class FakeLibc:
    """Records the ``mallopt`` and ``malloc_trim`` calls of a phase."""

    def __init__(self) -> None:
        self.calls: list[tuple] = []

    def mallopt(self, param: int, value: int) -> int:
        self.calls.append(("mallopt", param, value))
        return 1

    def malloc_trim(self, pad: int) -> int:
        self.calls.append(("trim", pad))
        return 1


@pytest.fixture
def libc(monkeypatch):
    fake = FakeLibc()
    monkeypatch.setattr(memory, "_glibc", lambda: fake)
    yield fake
    memory.untune_allocator()


def test_phases_do_nothing_unless_the_owner_tuned_the_allocator(libc):
    """A notebook's or a test's process: the phases leave glibc alone."""
    memory.untune_allocator()
    with memory.phase("chunks"), memory.phase("day_fit"):
        pass
    assert libc.calls == [] and not memory.tuned()


def test_phases_set_and_restore_the_glibc_thresholds(libc):
    """chunks: 32 MiB mmap and 256 MiB trim thresholds, the default trim threshold
    restored and the free heap returned on exit, also after an error; day_fit trims
    first and keeps 64 MiB of free heap while it runs, the default set back after it."""
    assert memory.tune_allocator() and memory.tuned()
    with pytest.raises(RuntimeError), memory.phase("chunks"):
        assert libc.calls == [("mallopt", -3, 32 << 20), ("mallopt", -1, 256 << 20)]
        raise RuntimeError("a chunk failed")
    assert libc.calls[2:] == [("mallopt", -1, 128 << 10), ("trim", 0)]
    libc.calls.clear()
    with memory.phase("day_fit"):
        assert libc.calls == [("trim", 0), ("mallopt", -1, 64 << 20)]
    assert libc.calls[2:] == [("mallopt", -1, 128 << 10)]
    with pytest.raises(ValueError, match="unknown allocator phase"), memory.phase("other"):
        pass


def test_without_glibc_tuning_is_refused(monkeypatch):
    monkeypatch.setattr(memory, "_glibc", lambda: None)
    assert not memory.tune_allocator() and not memory.tuned()
    assert not memory.keep_freed_arrays()


def test_only_the_program_tunes_its_process():
    """``cwproc retrieve`` (the program) tunes its process; importing the library and
    running a unit from Python (a notebook) does not."""
    code = (
        "import sys\n"
        "from cwproc import memory\n"
        "import cwproc.pipeline.stream, cwproc.pipeline.run\n"
        "assert not memory.tuned()\n"
        "import cwproc.cli._group as group\n"
        "group.exit_now = lambda code: print(int(memory.tuned()))\n"
        "from cwproc.cli import main\n"
        "main()\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code, "retrieve", "--help"],
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    expected = "1" if memory._glibc() is not None else "0"
    assert out.splitlines()[-1] == expected
    out = subprocess.run(
        [sys.executable, "-c", code, "info", "--help"], capture_output=True, text=True, check=True
    ).stdout
    assert out.splitlines()[-1] == "0"
