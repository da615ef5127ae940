"""The retrieval index (repro.motion.search.index): what the searches read, built once.

What is asserted: the cluster and clip-run radii bound every pose's distance from below
(``D(q, p) >= D(q, m) - r``), the bounds the exact search prunes with.
"""

from __future__ import annotations

import numpy as np
import pytest

from repro.motion.search.distance import aligned_distance
from repro.motion.search.index import group_centroids
from repro.motion.search.retrieval import make_queries


@pytest.fixture(scope="module")
def prepared(db, retriever):
    return [(c, retriever.prepare(pose, ch), sem) for c, pose, ch, sem in make_queries(db, 20, seed=7)]


def test_radii_bound_every_pose(db, retriever, prepared):
    r = retriever
    for c, q, sem in prepared[:20]:
        qn = q.q_n[0]
        dcent = r.centroid_index.distances(qn)
        for cl in range(r.k):
            b = r.cluster_block[cl][sem]
            if b is None:
                continue
            d = b.index.distances(qn)
            assert np.all(d >= dcent[cl] - r.retrieval_index.radius[sem][cl] - 1e-9)
            dg = aligned_distance(qn, group_centroids(r.db, b), r.weights)
            assert np.all(d >= (dg - b.gradius)[b.inv] - 1e-9)
