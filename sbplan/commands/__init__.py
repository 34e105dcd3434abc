"""One module per ``sbplan`` subcommand (see :mod:`sbplan.cli`)."""
