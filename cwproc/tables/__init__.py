"""The table store: tables computed once and kept on disk between runs (layer 2).

The physics layer computes the expensive tables of the turbulence retrieval from a few
parameters, without files, environment or terminal; this package keeps them:

* :mod:`cwproc.tables.store`: the disk cache (``<kind>-<sha256>.npz`` in the user cache
  folder, :func:`~cwproc.tables.store.default_cache_dir`, the one place that reads the
  environment), written atomically, and :func:`~cwproc.tables.store.code_digest`, the
  hash of the physics code a table depends on;
* :mod:`cwproc.tables.atable`: the A-function tables of Smalikho (2020), eqs. 15-17
  (cache, then the tables shipped in :mod:`cwproc.atables`, then a build with a
  :mod:`cwproc.progress` bar);
* :mod:`cwproc.tables.removed_share`: the removed-share curves of the VAD fit
  (Banakh et al. (1999), eqs. 15-16).
"""
