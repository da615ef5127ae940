"""The retrieval's helpers check their arguments at the entry (issue 23, sections 3, 6).

What is asserted: ``make_queries(db, 10**12)`` (which ran until killed) is a
:class:`RetrievalError` naming the count and its bound :data:`MAX_QUERIES`; ``retarget_to_tree`` given a motion or target that is not a Motion
is a :class:`MotionError` (was an ``AttributeError``).
"""

from __future__ import annotations

import numpy as np
import pytest

from repro.errors import MotionError, RetrievalError
from repro.motion.retargeting.dispatch import retarget_to_tree
from repro.motion.search.retrieval import MAX_QUERIES, MotionRetriever, make_queries


@pytest.fixture(scope="module")
def small(synthetic_db):
    return synthetic_db.select(np.arange(3))


@pytest.mark.parametrize("n", [MAX_QUERIES + 1, 10**12])
def test_query_counts_are_bounded(small, n):
    with pytest.raises(RetrievalError, match=rf"^n \(number of queries\) must be an integer in 0\.\.{MAX_QUERIES}"):
        make_queries(small, n)


def test_query_counts_in_range(small):
    assert len(make_queries(small, 3)) == 3


HOSTILE = ["x", None, float("nan"), 1j, -1, np.zeros(0), np.zeros((2, 7)), ["a"]]


@pytest.mark.parametrize("v", HOSTILE, ids=repr)
def test_retarget_to_tree_motion(small, v):
    ch = small.actor_skeleton(0)
    with pytest.raises(MotionError, match="^motion must be"):
        retarget_to_tree(v, ch)
    if v is not None:
        with pytest.raises(MotionError, match="^target must be"):
            retarget_to_tree(small.motion(0), ch, target=v)


@pytest.mark.parametrize("stats", ["x", 1, [], (), np.zeros(2)], ids=repr)
def test_search_exact_stats(small, stats):
    """``stats`` is filled after the search: anything but a dict (or None) was an AttributeError then."""
    from repro.motion.runtime.strike import one_frame

    r = MotionRetriever(small, seed=0)
    with pytest.raises(RetrievalError, match="^stats must be a dict"):
        r.search_exact([0.3, 1.4, 0.5], one_frame(small.motion(0), 0), small.actor_skeleton(0), "punch", stats=stats)
