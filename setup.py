"""Optional C extensions: the tokenizer of .hpl data lines (cwproc/io/_hpltok.c) and the
sums of the least-squares VAD fit (cwproc/stages/_vadsums.c).

All metadata lives in pyproject.toml; this file only declares the extensions. Both
are optional: where they cannot be compiled, the install succeeds and cwproc.io.halo uses
the pandas tokenizer instead (same results, about 2x slower on large files), and
cwproc.stages.vad_fit numpy's matrix products (the same fits to round-off).
"""

from setuptools import Extension, setup

setup(
    ext_modules=[
        Extension("cwproc.io._hpltok", ["cwproc/io/_hpltok.c"], optional=True),
        Extension("cwproc.stages._vadsums", ["cwproc/stages/_vadsums.c"], optional=True),
    ]
)
