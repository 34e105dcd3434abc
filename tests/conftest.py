"""Test-wide settings.

Hypothesis draws its examples from a seed derived from each test, not from the clock, so a run on
CI tests exactly what a run here tested (the project's rule: every random choice takes a seed),
and no example database carries failures from one checkout to the next. A new search with fresh
randomness: ``pytest --hypothesis-profile=explore`` (then add what it finds as ``@example``).
"""

from hypothesis import settings

settings.register_profile("default", derandomize=True, database=None)
settings.register_profile("explore", derandomize=False)
settings.load_profile("default")
