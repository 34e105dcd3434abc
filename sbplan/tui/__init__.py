"""The operator's terminal app, ``sbplan tui``: calibrate, detect, plan and replan.

A thin Textual layer over the library. Nothing in :mod:`sbplan` outside this package imports
Textual; import :mod:`sbplan.tui.app` only when the app is about to run.
"""
