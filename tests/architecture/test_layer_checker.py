"""The layer checker of ``test_layers.py`` itself, on small packages made in ``tmp_path``:
it sees cycles, string imports, forbidden imports and impure physics, and only imports."""

from __future__ import annotations

import sys
import textwrap
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import test_layers as layers


def _package(root: Path, files: dict[str, str]) -> Path:
    """A package ``cwproc`` under ``root`` holding ``files`` (path -> source)."""
    package = root / "cwproc"
    for name, text in {"__init__.py": "", **files}.items():
        path = package / name
        path.parent.mkdir(parents=True, exist_ok=True)
        for parent in path.relative_to(package).parents:
            (package / parent / "__init__.py").touch()
        path.write_text(textwrap.dedent(text), encoding="utf-8")
    return package


def test_a_two_module_cycle_through_a_lazy_import_is_found(tmp_path):
    package = _package(
        tmp_path,
        {
            "physics/a.py": "def f():\n    from cwproc.physics import b\n",
            "physics/b.py": "from cwproc.physics.a import f\n",
            "physics/c.py": "from cwproc.physics import a\n",
        },
    )
    (found,) = layers.cycles(package)
    assert found.splitlines()[0] == "cwproc.physics.a -> cwproc.physics.b -> cwproc.physics.a"
    assert "(cwproc/physics/a.py:2)" in found and "(cwproc/physics/b.py:1)" in found


def test_a_string_import_of_a_higher_layer_is_an_upward_import(tmp_path):
    package = _package(
        tmp_path,
        {
            "pipeline/__init__.py": "",
            "cli/run.py": "",
            "physics/x.py": """\
                import importlib

                def late():
                    return importlib.import_module("cwproc.pipeline")
                """,
            "physics/y.py": 'COMMANDS = {"run": "cwproc.cli.run:main"}\n',
        },
    )
    assert layers.upward_imports(package) == [
        "cwproc/physics/x.py:4: cwproc.physics.x -> cwproc.pipeline",
        "cwproc/physics/y.py:1: cwproc.physics.y -> cwproc.cli.run",
    ]


def test_only_strings_used_for_imports_count(tmp_path):
    """Docstrings and logger names naming a module are not imports."""
    package = _package(
        tmp_path,
        {
            "pipeline/__init__.py": "",
            "physics/quiet.py": '''\
                """Used by cwproc.pipeline (see cwproc.pipeline:run)."""
                import logging

                LOG = logging.getLogger("cwproc.pipeline")
                ''',
        },
    )
    assert layers.upward_imports(package) == []
    assert layers.import_graph(package)["cwproc.physics.quiet"] == {}


def test_lazy_tables_of_submodules_and_of_homes_are_imports(tmp_path):
    package = _package(
        tmp_path,
        {
            "stages/__init__.py": """\
                import importlib

                _MODULES = ("qc", "not_a_module")

                def __getattr__(name):
                    return importlib.import_module(f"{__name__}.{name}")
                """,
            "stages/qc.py": "",
            "io/__init__.py": """\
                from importlib import import_module

                _HOMES = {"read": "cwproc.io.reader", "fit": "cwproc.stages.qc"}

                def __getattr__(name):
                    return getattr(import_module(_HOMES[name]), name)
                """,
            "io/reader.py": "",
        },
    )
    graph = layers.import_graph(package)
    assert set(graph["cwproc.stages"]) == {"cwproc.stages.qc"}
    assert set(graph["cwproc.io"]) == {"cwproc.io.reader", "cwproc.stages.qc"}
    assert layers.upward_imports(package) == [
        "cwproc/io/__init__.py:3: cwproc.io -> cwproc.stages.qc"
    ]


def test_a_compiled_submodule_is_a_module_not_its_package(tmp_path):
    package = _package(tmp_path, {"io/__init__.py": "from cwproc.io import reader\n"})
    (package / "io" / "_tok.c").write_text("/* C */\n")
    (package / "io" / "reader.py").write_text("from cwproc.io import _tok\n")
    assert layers.cycles(package) == []
    assert set(layers.import_graph(package)["cwproc.io.reader"]) == {"cwproc.io._tok"}


def test_a_stage_may_not_import_the_configuration(tmp_path):
    package = _package(
        tmp_path,
        {"config.py": "", "stages/eps.py": "def f():\n    from cwproc.config import x\n"},
    )
    assert layers.upward_imports(package) == [
        "cwproc/stages/eps.py:2: cwproc.stages.eps -> cwproc.config"
    ]


def test_physics_with_files_environment_or_terminal_is_impure(tmp_path):
    package = _package(
        tmp_path,
        {
            "progress.py": "",
            "physics/dirty.py": """\
                import os
                import sys
                import tempfile

                import numpy as np

                from cwproc import progress

                def f(path, a):
                    home = os.environ["HOME"]
                    print(home, file=sys.stderr)
                    np.savez(path, a=a)
                    path.write_text("x")
                    with open(path) as fh:
                        return fh.read()
                """,
            "physics/clean.py": "import numpy as np\n\ndef g(a):\n    return np.sum(a)\n",
        },
    )
    assert layers.impure_physics(package) == [
        "cwproc/physics/dirty.py:10: os.environ",
        "cwproc/physics/dirty.py:11: print(",
        "cwproc/physics/dirty.py:11: sys.stderr",
        "cwproc/physics/dirty.py:12: np.savez",
        "cwproc/physics/dirty.py:13: .write_text",
        "cwproc/physics/dirty.py:14: open(",
    ]
    assert layers.upward_imports(package) == [
        "cwproc/physics/dirty.py:3: cwproc.physics.dirty -> tempfile",
        "cwproc/physics/dirty.py:7: cwproc.physics.dirty -> cwproc.progress",
    ]


def test_a_layer_may_name_a_package_that_does_not_exist_yet():
    """Streams add their packages one after the other: a name of LAYERS without a
    module is fine, a module without a layer is not."""
    assert layers.layer_of("cwproc.memory") == 0
    assert layers.layer_of("cwproc.metadata.canonical") == layers.layer_of("cwproc.io")
    assert layers.layer_of("cwproc.tables.atable") == layers.layer_of("cwproc.io")
    assert layers.layer_of("cwproc.physics.atable") < layers.layer_of("cwproc.tables")
