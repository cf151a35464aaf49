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


def pytest_configure(config) -> None:
    """Under ``-n N`` schedule as xdist's ``loadgroup``: tests spread one by one as with ``load``,
    but those marked ``@pytest.mark.xdist_group(name)`` run on one worker, so the module-scoped
    fixture they share (a detector run, a campaign, a process start-up) is built once, not once
    per worker that happens to get one of them."""
    # xdist registers the mark itself; registered here too for runs with ``-p no:xdist``
    config.addinivalue_line(
        "markers", "xdist_group(name): run on the same xdist worker as the group's other tests"
    )
    if getattr(config.option, "dist", "no") == "load":
        config.option.dist = "loadgroup"
