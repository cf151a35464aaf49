"""Work on whole scans in blocks of at most :data:`BLOCK_BYTES` per temporary array.

A numpy temporary under 128 KiB (glibc's default mmap threshold) is served from memory the
allocator keeps; a larger one is mapped afresh each time and every page of it faults on first
touch. On the 2-core benchmark VM an element-wise operation on 32-256 Ki float64 cost 3-5 ns per
element that way against ~1 ns on blocks of up to 16 Ki (measured), and the detector's full-scan
passes (a 64 x 4,000 HDL-64 image, ~400 k points per frame) made ~5,700 page faults per frame (~90
after). Passes over scans therefore run block by block; the results are element-wise the same.
"""

from __future__ import annotations

from collections.abc import Iterator

BLOCK_BYTES = 120 * 1024  # per temporary of a block
BLOCK_ELEMENTS = BLOCK_BYTES // 8  # float64 elements per block


def spans(n: int, size: int = BLOCK_ELEMENTS) -> Iterator[slice]:
    """Consecutive slices of ``range(n)`` of ``size`` items (the last may be shorter)."""
    for start in range(0, n, size):
        yield slice(start, min(start + size, n))


def row_spans(n_rows: int, row_elements: int, size: int = BLOCK_ELEMENTS) -> Iterator[slice]:
    """Slices of whole rows holding about ``size`` elements each (at least one row per slice)."""
    return spans(n_rows, max(1, size // max(row_elements, 1)))
