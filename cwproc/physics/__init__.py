"""Pure physics: geometry, spectra, probe-volume transfer functions, A-functions, VAD errors."""
