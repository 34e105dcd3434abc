"""Built-in mappers of sbplan, registered through the sbplan entry-point group like any plugin."""
