"""Widgets of the sbplan terminal app."""
