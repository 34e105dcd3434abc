"""Built-in extractors of sbplan, registered through the sbplan entry-point group like any plugin."""
