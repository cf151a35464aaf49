"""``python -m negobs_gym.cli`` is the ``negobs`` console script (for subprocesses and tests)."""

from negobs_gym.cli import main

raise SystemExit(main())
