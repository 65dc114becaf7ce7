"""Reference pages generated from the code: variables, options, commands, Python API.

``python -m cwproc.reference_docs docs/`` rewrites ``docs/variables.md``,
``docs/config.md``, ``docs/commands.md`` and ``docs/api.md``; a test checks that the
committed pages equal what the code generates, so the documentation cannot drift from
the metadata table, the configuration dataclasses, the commands and the docstrings.
"""

from __future__ import annotations

import ast
import dataclasses
import inspect
import re
import sys
import typing
from pathlib import Path

from cwproc import config as config_module
from cwproc.config import Config, preset_names
from cwproc.metadata import VARIABLES


def variables_markdown() -> str:
    """Markdown table of every variable cwproc writes (name, units, standard name, meaning)."""
    lines = [
        "# Product variables",
        "",
        "Generated from `cwproc/metadata/` by `python -m cwproc.reference_docs docs/`;",
        "do not edit by hand.",
        "",
        "| variable | units | standard_name | long_name | notes |",
        "|---|---|---|---|---|",
    ]
    for name, meta in VARIABLES.items():
        notes = meta.comment or ""
        if meta.flag_meanings:
            notes = (notes + "; " if notes else "") + f"flags: {meta.flag_meanings}"
        lines.append(
            f"| `{name}` | {meta.units or ''} | {meta.standard_name or ''} | "
            f"{_cell(meta.long_name)} | {_cell(notes)} |"
        )
    return "\n".join(lines) + "\n"


def _field_comments(cls: type) -> dict[str, str]:
    """The ``#:`` comments written above each field of a dataclass in its source."""
    source = inspect.getsource(cls)
    lines = source.splitlines()
    tree = ast.parse(source)
    out: dict[str, str] = {}
    body = tree.body[0].body  # type: ignore[attr-defined]
    for node in body:
        if isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            k = node.lineno - 2
            doc: list[str] = []
            while k >= 0 and lines[k].strip().startswith("#:"):
                doc.insert(0, lines[k].strip()[2:].strip())
                k -= 1
            out[node.target.id] = " ".join(doc)
    return out


def preset_description(name: str) -> str:
    """The leading comment of a preset file, as one line."""
    from importlib import resources

    text = resources.files("cwproc.configs").joinpath(f"{name}.toml").read_text("utf-8")
    words = []
    for line in text.splitlines():
        if not line.startswith("#"):
            break
        words.append(line.lstrip("#").strip())
    return " ".join(words)


def _type_name(tp: object) -> str:
    text = str(tp).replace("typing.", "")
    return _cell(text.replace("<class '", "").replace("'>", ""))


def _cell(text: str) -> str:
    """Text safe inside a Markdown table cell."""
    return text.replace("|", "\\|")


def config_markdown() -> str:
    """Markdown reference of every configuration section, option, type and default."""
    lines = [
        "# Configuration reference",
        "",
        "Generated from `cwproc/config.py` by `python -m cwproc.reference_docs docs/`;",
        "do not edit by hand. A configuration is a TOML file with the sections below; every",
        "key is optional and unknown keys, wrong types and impossible values are refused",
        "with a message naming the file and the key. Presets: "
        + ", ".join(f"`{p}`" for p in preset_names())
        + " (`cwproc retrieve -c streamline ...`; files in `configs/`).",
        "",
    ]
    lines += ["## Presets", "", "| preset | what it is for |", "|---|---|"]
    for name in preset_names():
        lines.append(f"| `{name}` | {_cell(preset_description(name))} |")
    lines.append("")
    hints = typing.get_type_hints(Config)
    for f in dataclasses.fields(Config):
        if f.name == "source":
            continue
        section = hints[f.name]
        if not dataclasses.is_dataclass(section):
            lines += [
                f"## [{f.name}.<format>]",
                "",
                "Options of the reader of one format (validated by that reader), e.g. "
                "`[reader.meteo2]`, `[reader.toa5]`; see the reader's page in `docs/`.",
                "",
            ]
            continue
        lines += [f"## [{f.name}]", "", (section.__doc__ or "").strip(), ""]
        lines += ["| key | type | default | meaning |", "|---|---|---|---|"]
        comments = _field_comments(section)
        sub_hints = typing.get_type_hints(section)
        for sub in dataclasses.fields(section):
            default = sub.default if sub.default is not dataclasses.MISSING else ""
            lines.append(
                f"| `{sub.name}` | {_type_name(sub_hints[sub.name])} | `{default!r}` | "
                f"{_cell(comments.get(sub.name, ''))} |"
            )
        lines.append("")
    return "\n".join(lines)


def _command_sections(cmd, path: str, ctx) -> list[str]:
    import click

    # click caches each command's help option from the first context that asked for it
    # (a command invoked on its own, e.g. in a test, caches "--help" without "-h"); drop
    # the cache so the page always shows the options of the real command line
    if hasattr(cmd, "_help_option"):
        cmd._help_option = None
    lines = [f"## `{path}`", "", "```text", cmd.get_help(ctx).rstrip(), "```", ""]
    if isinstance(cmd, click.Group):
        for name in cmd.list_commands(ctx):
            sub = cmd.get_command(ctx, name)
            sub_ctx = click.Context(sub, info_name=name, parent=ctx)
            lines += _command_sections(sub, f"{path} {name}", sub_ctx)
    return lines


def commands_markdown() -> str:
    """Every command's ``--help``, as one page."""
    import click

    from cwproc.cli import main

    settings = {**main.context_settings, "terminal_width": 100, "max_content_width": 100}
    ctx = click.Context(main, info_name="cwproc", **settings)
    lines = [
        "# Commands",
        "",
        "Generated from the command-line help by `python -m cwproc.reference_docs docs/`;",
        "do not edit by hand. Every command exits 0 when all inputs were processed and",
        "non-zero otherwise, with one line per failed input naming the file, the line and",
        "the problem.",
        "",
        "Common to the commands that write products (`retrieve`, `sf-type`, `batch`):",
        "",
        "- the configuration (`-c`) and the output directory (`-o`, created if missing, a",
        "  file written and removed in it) are checked before anything is read: a wrong key",
        "  or an unwritable directory stops the run at once (exit 2);",
        "- a file of another instrument than the configuration's (`-c zephir300` on Stream",
        "  Line `.hpl` files) is a failure naming the file and both instruments (exit 1);",
        "  files of formats the configuration does not read, found in folders, get one note;",
        "- a product already in the output directory is **replaced**, and a note names it",
        "  (`note: 2 product(s) of an earlier run replaced: ...`); `batch` replaces only",
        "  the products of new or changed inputs (its ledger);",
        "- a product whose every value would be missing (e.g. the turbulence product of a",
        "  day whose VADs are too few for a block) is **not written**; a note names it and",
        "  the flags that say why;",
        "- Ctrl-C stops any command with one line and exit status 130; products are",
        "  published whole, so those finished are kept and none is half-written;",
        "- on a terminal, steps longer than 2 s show a progress bar on stderr; nothing is",
        "  shown with `-q` or when stderr is not a terminal (cron, a pipe, a log file).",
        "",
    ]
    return "\n".join(lines + _command_sections(main, "cwproc", ctx))


#: sections of the API page: title and the modules whose public names it lists
API_SECTIONS = (
    ("Reading, retrieving and writing", ("cwproc.api", "cwproc.io.scan_join")),
    ("Configuration", ("cwproc.config", "cwproc.config_products")),
    ("Errors", ("cwproc.errors",)),
)


def first_paragraph(obj: object) -> str:
    """The first paragraph of the docstring of ``obj`` as one Markdown line.

    Sphinx roles (``:func:`x```) and double back-quotes become plain code spans.
    """
    doc = inspect.getdoc(obj) or ""
    text = " ".join(doc.split("\n\n")[0].split())
    return re.sub(r":[a-z]+:`~?([^`]+)`", r"`\1`", text).replace("``", "`")


class _Shown:
    """An annotation written as text (``from __future__ import annotations``), shown bare."""

    def __init__(self, text: str) -> None:
        self.text = text

    def __repr__(self) -> str:
        return self.text


def _signature(obj: object, *, bound: bool = False) -> str:
    """``(a: int = 1, *, b: str = 'x') -> T`` of a function or class, as written.

    ``bound``: leave out the first parameter (``self`` or ``cls`` of a method). Private
    parameters (leading ``_``) and the ``-> None`` of classes are left out.
    """
    sig = inspect.signature(obj)
    params = list(sig.parameters.values())[1 if bound else 0 :]
    shown = [
        p.replace(annotation=_Shown(p.annotation)) if isinstance(p.annotation, str) else p
        for p in params
        if not p.name.startswith("_")
    ]
    ret = sig.return_annotation
    if inspect.isclass(obj):
        ret = inspect.Signature.empty
    elif isinstance(ret, str):
        ret = _Shown(ret)
    return str(sig.replace(parameters=shown, return_annotation=ret))


def _members(cls: type) -> list[tuple[str, object]]:
    """Public methods and properties defined in ``cls`` itself (and ``__getitem__``)."""
    out = []
    for name, value in vars(cls).items():
        if name.startswith("_") and name != "__getitem__":
            continue
        if isinstance(value, classmethod | staticmethod):
            value = value.__func__
        if isinstance(value, property) or inspect.isfunction(value):
            out.append((name, value))
    return out


def _api_entry(qualified: str, obj: object) -> list[str]:
    """The lines of one public name: heading, signature and first docstring paragraph."""
    kind = "class" if inspect.isclass(obj) else "function"
    lines = [f"### `{qualified}`", ""]
    try:
        lines += ["```python", f"{qualified}{_signature(obj)}", "```", ""]
    except ValueError:  # a class without a signature of its own (an exception)
        pass
    lines += [first_paragraph(obj) or f"({kind})", ""]
    if inspect.isclass(obj):
        for name, member in _members(obj):
            if isinstance(member, property):
                lines.append(f"- `.{name}` (property): {first_paragraph(member)}")
            else:
                call = _signature(member, bound=True)
                label = f"[{call[1:].split(')')[0]}]" if name == "__getitem__" else f".{name}{call}"
                lines.append(f"- `{label}`: {first_paragraph(member)}")
        if _members(obj):
            lines.append("")
    return lines


def api_markdown() -> str:
    """The Python API: every name of ``cwproc.__all__`` and ``cwproc.stages.__all__``."""
    import cwproc
    from cwproc import stages

    lines = [
        "# Python API",
        "",
        "Generated from the docstrings by `python -m cwproc.reference_docs docs/`; do not",
        "edit by hand. `import cwproc` gives every name below (imported when first used,",
        "so the command line stays fast); worked examples that run on the shipped",
        "samples are [examples/first_day.py](examples/first_day.py) (the products of a",
        "day) and [examples/stages.py](examples/stages.py) (each stage on its own).",
        "",
        "```python",
        "import cwproc",
        "",
        'result = cwproc.retrieve("sample_data/streamline", "streamline")',
        'wind = result["wind"]  # xarray.Dataset with CF units',
        "",
        'scans = cwproc.read("sample_data/streamline/*.hpl")  # one record, 12 scans',
        "wind = cwproc.stages.fit_vad(scans)  # units and long names attached",
        "```",
        "",
        "Join the files of a record with `cwproc.read([...])` or `cwproc.concat_scans`,",
        "never `xarray.concat`: every file numbers its scans from 0, so scan k of each",
        "file would be fitted as one rotation. The scan stages (`screen_radial_velocity`,",
        "`fit_vad`, `azimuth_structure_function`) refuse such a dataset with a message",
        "that says so. `cwproc.retrieve` and `cwproc.write` accept datasets too; without",
        "a configuration each unit takes its instrument's preset (a note names it).",
        "",
    ]
    public = [n for n in cwproc.__all__ if n not in ("__version__", "stages")]
    for title, modules in API_SECTIONS:
        lines += [f"## {title}", ""]
        for name in public:
            obj = getattr(cwproc, name)
            if getattr(obj, "__module__", None) in modules:
                lines += _api_entry(f"cwproc.{name}", obj)
    lines += [
        "## Stages",
        "",
        first_paragraph(stages),
        "",
        "Their keyword arguments default to the values of the presets (`streamline`,",
        "`zephir300`, `meteo2`).",
        "",
    ]
    for name in stages.__all__:
        lines += _api_entry(f"cwproc.stages.{name}", getattr(stages, name))
    return "\n".join(lines).rstrip("\n") + "\n"


PAGES = {
    "variables.md": variables_markdown,
    "config.md": config_markdown,
    "commands.md": commands_markdown,
    "api.md": api_markdown,
}


def write_pages(directory: str | Path) -> list[Path]:
    """Write the generated pages into ``directory``."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    written = []
    for name, make in PAGES.items():
        path = directory / name
        path.write_text(make(), encoding="utf-8")
        written.append(path)
    return written


if __name__ == "__main__":  # pragma: no cover - exercised by the docs test through the API
    for page in write_pages(sys.argv[1] if len(sys.argv) > 1 else "docs"):
        print(f"wrote {page}")

__all__ = [
    "api_markdown",
    "config_markdown",
    "config_module",
    "variables_markdown",
    "write_pages",
]
