"""Configuration presets (TOML) shipped with cwproc."""
