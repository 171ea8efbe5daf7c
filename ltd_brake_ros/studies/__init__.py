"""Offline uses of the simulator: runs, validation, calibration, the reference solver."""
