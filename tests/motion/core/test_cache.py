"""LRUCache: bounded, least recently used evicted first, one value per key."""

import threading

import pytest

from repro.errors import MotionError
from repro.motion.core.cache import LRUCache


def test_makes_once_and_evicts_the_least_recently_used():
    made = []
    c = LRUCache(2)
    mk = lambda k: (lambda: made.append(k) or k * 10)  # noqa: E731
    assert c.get(1, mk(1)) == 10 and c.get(2, mk(2)) == 20
    assert c.get(1, mk(1)) == 10  # hit: 1 is now the most recent
    c.get(3, mk(3))  # evicts 2
    assert made == [1, 2, 3] and len(c) == 2 and 2 not in c and 1 in c
    c.clear()
    assert len(c) == 0


@pytest.mark.parametrize("bad", [0, -1, 2.5, "3", None])
def test_bound_must_be_a_positive_integer(bad):
    with pytest.raises(MotionError):
        LRUCache(bad)


def test_concurrent_gets_agree_on_one_value():
    c = LRUCache(4)
    out = []
    ts = [threading.Thread(target=lambda: out.append(c.get("k", object))) for _ in range(8)]
    for t in ts:
        t.start()
    for t in ts:
        t.join()
    assert len({id(v) for v in out}) == 1
