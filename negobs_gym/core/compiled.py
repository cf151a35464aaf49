"""The one way this package compiles a per-element loop: :func:`kernel` (numba).

Used where numpy needs dozens of passes over gathered columns for what one loop does per element
(pair distances, polar binning, density windows, ray setup; measured figures in
docs/performance.md). The settings hold the package's rules:

- no fast-math: operations are neither reordered nor fused, so a kernel that spells out numpy's
  operation order gives numpy's results bit for bit (each kernel is tested against a numpy
  reference);
- ``error_model="numpy"``: a division by zero gives inf/NaN as in numpy instead of raising;
- ``cache=True``: compiled once per machine into ``__pycache__`` beside the module, or the user's
  cache directory where the install is read-only (``NUMBA_CACHE_DIR`` overrides both); the first
  call in a fresh install compiles, ~1-2 s per module, later processes load it in milliseconds;
- ``nogil=True``: a kernel lets other threads run (the Embree cast threads, vector-env threads).
"""

from __future__ import annotations

from numba import njit

kernel = njit(cache=True, nogil=True, error_model="numpy")
