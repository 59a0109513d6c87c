"""Readers and writers: pose JSON and CSV, calibration TOML."""
