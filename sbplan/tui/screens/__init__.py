"""Screens of the sbplan terminal app: calibration, detection, route, help."""
