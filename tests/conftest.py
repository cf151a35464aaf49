"""Hypothesis profiles: the default run draws the same cases every time; ``explore`` draws new ones.

The default suite gates every change, so a property test must not pass on one run and fail on the
next for cases it happened to draw: ``repeatable`` seeds each test from its own source. Looking for
new counterexamples is a separate run, ``python -m pytest -q --hypothesis-profile explore``
(fresh random draws each run, failures kept in ``.hypothesis/`` and replayed first); pin what it
finds with ``@example``.
"""

from __future__ import annotations

from hypothesis import settings

settings.register_profile("repeatable", derandomize=True, database=None)
settings.register_profile("explore", derandomize=False, print_blob=True)
settings.load_profile("repeatable")
