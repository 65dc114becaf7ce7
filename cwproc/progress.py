"""Progress of long steps on the terminal, and nothing anywhere else.

The command line decides once per run whether progress is shown
(:func:`shown_on`: standard error is a terminal and ``-q`` was not given) and turns it on
for the run with :func:`reporting`. Library code reports its long loops through
:func:`track` and :func:`bar`, which do nothing unless a caller turned progress on: a
notebook, a cron job (standard error not a terminal), a Dask worker and the tests see no
bar. A bar appears only once its step has taken :data:`DELAY_S` seconds, so short steps
stay silent. The bars are `tqdm <https://tqdm.github.io>`_'s, written to standard error.

Examples
--------
>>> from cwproc import progress
>>> with progress.reporting(progress.shown_on(quiet=False)):
...     total = sum(progress.track(range(3), desc="adding"))
"""

from __future__ import annotations

import contextlib
import contextvars
import sys
from collections.abc import Iterable, Iterator
from typing import IO, Any, TypeVar

T = TypeVar("T")

#: seconds a step runs before its bar appears (steps shorter than this show nothing)
DELAY_S = 2.0

_ON: contextvars.ContextVar[bool] = contextvars.ContextVar("cwproc_progress", default=False)


def shown_on(*, quiet: bool, stream: IO[str] | None = None) -> bool:
    """Whether a command shows progress: ``stream`` (stderr) is a terminal, not ``quiet``."""
    stream = sys.stderr if stream is None else stream
    if quiet or stream is None:
        return False
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):  # a closed or replaced stream
        return False


def is_on() -> bool:
    """Whether progress is being reported in this context."""
    return _ON.get()


@contextlib.contextmanager
def reporting(on: bool) -> Iterator[None]:
    """Report progress inside the ``with`` block when ``on`` (the command line's switch)."""
    token = _ON.set(bool(on))
    try:
        yield
    finally:
        _ON.reset(token)


def _tqdm(**kwargs: Any):
    from tqdm import tqdm

    return tqdm(
        file=sys.stderr,
        delay=DELAY_S,
        leave=False,
        dynamic_ncols=True,
        mininterval=0.25,
        **kwargs,
    )


def track(
    iterable: Iterable[T], *, desc: str, total: float | None = None, unit: str = "it"
) -> Iterable[T]:
    """``iterable`` itself, with a bar on the terminal while it is consumed (when on)."""
    if not _ON.get():
        return iterable
    if total is None:
        try:
            total = len(iterable)  # type: ignore[arg-type]
        except TypeError:
            total = None
    return _tqdm(iterable=iterable, desc=desc, total=total, unit=unit)


class _Silent:
    """The bar of a run without progress: every call does nothing."""

    def update(self, n: float = 1) -> None:
        """Nothing."""

    def set_postfix_str(self, text: str) -> None:
        """Nothing."""


@contextlib.contextmanager
def bar(*, desc: str, total: float | None = None, unit: str = "it") -> Iterator[Any]:
    """A bar advanced by hand (``.update(n)``), or a silent stand-in when progress is off."""
    if not _ON.get():
        yield _Silent()
        return
    handle = _tqdm(desc=desc, total=total, unit=unit)
    try:
        yield handle
    finally:
        handle.close()
