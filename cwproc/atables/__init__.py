"""Prebuilt A-function tables shipped with cwproc (``tools/build_atables.py``).

:func:`cwproc.tables.atable.get_a_table` looks here when a table is not in the user
cache, so that the shipped presets on the shipped samples never wait for a build.
"""
