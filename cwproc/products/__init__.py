"""Products: the only home of variable names, units, flags, titles and references,
and the writer that turns a stage's Dataset into a CF-1.10 / ACDD-1.3 NetCDF file."""
