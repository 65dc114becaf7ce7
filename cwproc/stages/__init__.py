"""Processing stages: ``f(ds: xarray.Dataset, *, params) -> xarray.Dataset``, no I/O."""
