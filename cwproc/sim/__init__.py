"""The virtual instrument: turbulent wind fields, cw and pulsed lidars, sonic series."""
