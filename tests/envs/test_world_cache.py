"""Settled worlds kept between episodes: LRU eviction, closing, and the heap handed back."""

from __future__ import annotations

import ctypes

import gymnasium as gym
import pytest

import negobs_gym  # noqa: F401 - registers the envs
from negobs_gym.envs.world_cache import WorldCache, release_freed_memory
from tests.helpers import HAS_PROC_STATM, rss_mb


class _FakeWorld:
    """Stands in for a CachedWorld: the cache only calls ``close``."""

    def __init__(self) -> None:
        self.closed = False

    def close(self) -> None:
        self.closed = True


def test_cache_closes_the_least_recently_used_world_beyond_its_limit():
    cache = WorldCache(2)
    a, b, c = _FakeWorld(), _FakeWorld(), _FakeWorld()
    cache.put("a", a)
    cache.put("b", b)
    assert cache.get("a") is a  # a is now the most recently used
    cache.put("c", c)
    assert b.closed and not a.closed and not c.closed
    assert len(cache) == 2 and cache.evictions == 1
    assert cache.get("b") is None and cache.misses == 1 and cache.hits == 1
    cache.close()
    assert a.closed and c.closed and len(cache) == 0


def test_a_world_held_ahead_joins_the_kept_ones_on_its_key_and_is_closed_on_any_other():
    cache = WorldCache(1)
    kept, ahead, stale, later = _FakeWorld(), _FakeWorld(), _FakeWorld(), _FakeWorld()
    cache.put("kept", kept)
    cache.hold_ahead("stale", stale)
    cache.hold_ahead("next", ahead)  # replaces the one held before
    assert stale.closed and "next" in cache and len(cache) == 1
    assert cache.get("next") is ahead  # kept now, the older world dropped beyond the limit
    assert kept.closed and not ahead.closed and len(cache) == 1
    cache.hold_ahead("unused", later)
    assert cache.get("next") is ahead and later.closed  # another draw: the held world is gone
    counts = cache.counts()
    assert counts == {"kept": 1, "held_ahead": 0, "hits": 2, "ahead_hits": 1, "misses": 0, "evictions": 3}
    cache.hold_ahead("x", _FakeWorld())
    cache.close()
    assert ahead.closed and cache.counts()["held_ahead"] == 0


def test_a_reset_onto_a_new_terrain_closes_the_last_episodes_world():
    env = gym.make(
        "negobs_gym/OffroadNav-v0", overrides={"terrain.params.length_m": 60.0}
    )  # builds ~4x faster
    base = env.unwrapped
    assert base.scenario.episode.world_cache_size == 1
    env.reset(seed=0)
    first = base._world
    env.reset(seed=1)
    assert first.closed, "with one world kept, the ended episode's world must be released"
    assert not base._world.closed and len(base._worlds) == 1 and base._worlds.evictions == 1
    env.step(env.action_space.sample())  # the env runs on its new world
    env.close()


def _has_malloc_trim() -> bool:
    try:
        ctypes.CDLL(None).malloc_trim  # noqa: B018 - probing for the symbol
    except (OSError, AttributeError):
        return False
    return True


@pytest.mark.skipif(not (_has_malloc_trim() and HAS_PROC_STATM), reason="needs glibc")
def test_release_freed_memory_hands_fragmented_heap_back():
    # 1 kB buffers come from malloc's heap (not Python's small-object arenas, not mmap); freed,
    # glibc keeps their pages while a live block sits above them.
    release_freed_memory()  # so the blocks take new pages, not those earlier tests freed
    start = rss_mb()
    blocks = [bytearray(1000) for _ in range(130_000)]  # ~130 MB
    keep = blocks[-1]  # one block at the top of the heap stops the heap shrinking by itself
    del blocks
    before = rss_mb()
    assert before - start > 100.0, "the freed blocks must still be resident for the test to mean anything"
    assert release_freed_memory()
    assert before - rss_mb() > 50.0
    del keep
