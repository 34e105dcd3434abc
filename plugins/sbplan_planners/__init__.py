"""Built-in planners of sbplan, registered through the sbplan entry-point group like any plugin."""
