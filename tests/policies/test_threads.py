"""``torch_threads``: torch's thread count inside a block, restored after it, errors included."""

from __future__ import annotations

import pytest
import torch

from negobs_gym.policies.threads import torch_threads


def test_the_count_holds_inside_the_block_and_is_restored_after() -> None:
    before = torch.get_num_threads()
    other = 1 if before != 1 else 2
    with torch_threads(other):
        assert torch.get_num_threads() == other
    assert torch.get_num_threads() == before
    with pytest.raises(RuntimeError, match="inside"), torch_threads(other):
        raise RuntimeError("inside")
    assert torch.get_num_threads() == before
