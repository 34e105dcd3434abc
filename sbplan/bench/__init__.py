"""Benchmarks behind ``sbplan bench``: one module per benchmark with ``HELP``,
``add_arguments(parser)`` and ``run(args)``."""
