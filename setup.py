"""Optional C tokenizer of .hpl data lines (cwproc/io/_hpltok.c).

All metadata lives in pyproject.toml; this file only declares the extension. It is
optional: where it cannot be compiled, the install succeeds and cwproc.io.halo uses the
pandas tokenizer instead (same results, about 2x slower on large files).
"""

from setuptools import Extension, setup

setup(
    ext_modules=[
        Extension("cwproc.io._hpltok", ["cwproc/io/_hpltok.c"], optional=True),
    ]
)
