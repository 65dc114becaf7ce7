"""Exceptions raised by cwproc.

Every problem with an input file is raised as :class:`InputFileError`, whose
message names the file, the line (when one applies) and the problem, so that the
command line can print exactly one line per failed input::

    data/VAD_91_20240101_000000.hpl:18: gate line has 3 fields, expected 4 or 5
"""

from __future__ import annotations

import os


class CwprocError(Exception):
    """Base class of every error that cwproc reports to the user as one line."""


#: longest problem text of an error line (characters)
PROBLEM_MAX = 300


def one_line(text: str, limit: int = PROBLEM_MAX) -> str:
    """``text`` as one line of at most ``limit`` characters (control characters shown).

    A file with lone-CR line ends is "one line" to a reader; quoting it must not put
    the whole file (110 kB of a WindCube .sta) into an error message.
    """
    flat = "".join(c if c.isprintable() else repr(c)[1:-1] for c in str(text))
    return flat if len(flat) <= limit else flat[: limit - 1] + "…"


class InputFileError(CwprocError):
    """A problem with one input file.

    Parameters
    ----------
    path : str or os.PathLike
        The file.
    problem : str
        What is wrong, in plain words.
    line : int, optional
        1-based line number (for binary files: the record number, see ``unit``).
    unit : str, optional
        What ``line`` counts, ``"line"`` by default (``"record"``, ``"byte"``).
    """

    def __init__(
        self,
        path: str | os.PathLike,
        problem: str,
        line: int | None = None,
        *,
        unit: str = "line",
    ) -> None:
        self.path = os.fspath(path)
        self.problem = one_line(problem)
        self.line = line
        self.unit = unit
        super().__init__(self.__str__())

    def __str__(self) -> str:
        if self.line is None:
            return f"{self.path}: {self.problem}"
        if self.unit == "line":
            return f"{self.path}:{self.line}: {self.problem}"
        return f"{self.path}: {self.unit} {self.line}: {self.problem}"


class ConfigError(CwprocError):
    """A problem with a configuration file or value.

    Parameters
    ----------
    source : str
        The configuration file (or ``"<preset name>"``).
    key : str
        Dotted key, e.g. ``"qc.snr_min"``.
    problem : str
        What is wrong.
    """

    def __init__(self, source: str, key: str, problem: str) -> None:
        self.source = source
        self.key = key
        self.problem = problem
        super().__init__(f"{source}: {key}: {problem}")


class ProductError(CwprocError):
    """A product cannot be made or written (e.g. output directory not writable)."""
