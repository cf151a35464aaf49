"""``python -m negobs_gym`` runs the quick-start demo (:mod:`negobs_gym.demo`)."""

from negobs_gym.demo import main

raise SystemExit(main())
