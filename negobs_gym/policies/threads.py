"""Torch's intra-op thread count for a block of code."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

import torch


@contextmanager
def torch_threads(count: int) -> Iterator[None]:
    """Run the block with torch on ``count`` intra-op threads, then restore the count it had.

    Results can differ in their last bits between thread counts (weight initialisation, a
    policy's forward pass), so what must be reproducible runs on a fixed count.
    """
    before = torch.get_num_threads()
    torch.set_num_threads(count)
    try:
        yield
    finally:
        torch.set_num_threads(before)
