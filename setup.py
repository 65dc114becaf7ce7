"""Optional C extensions: the .hpl tokenizer and the simulator's field interpolation.

All metadata lives in pyproject.toml; this file only declares the extensions. They are
optional: where they cannot be compiled, the install succeeds and cwproc uses numpy
instead (same results): cwproc.io.halo the pandas tokenizer (about 2x slower on large
files), cwproc.sim.field3d a numpy trilinear interpolation (about 10x slower), cwproc.sim.cw
its Doppler spectra in numpy (the same numbers, about 3x slower), cwproc.physics the
splines of the A-table build in numpy (the same numbers, bit for bit; a first table
about 1.4x slower).
"""

from setuptools import Extension, setup

setup(
    ext_modules=[
        Extension("cwproc.io._hpltok", ["cwproc/io/_hpltok.c"], optional=True),
        Extension("cwproc.sim._trilinear", ["cwproc/sim/_trilinear.c"], optional=True),
        Extension("cwproc.sim._sinc2", ["cwproc/sim/_sinc2.c"], optional=True),
        Extension("cwproc.physics._pieces", ["cwproc/physics/_pieces.c"], optional=True),
    ]
)
