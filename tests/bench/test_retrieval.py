"""repro.bench.retrieval.time_search: the searches' latency on random queries (no time asserted).

What is asserted: it reports a positive median and a 99th percentile above it per method, the
pruned search's agreement with the exhaustive optimum and its fallbacks for every query; its
arguments (query count up to :data:`MAX_QUERIES`: ``10**12`` ran until killed, repeats,
methods, a retriever of its database) are checked, each refusal a :class:`ReproError`.
"""

from __future__ import annotations

import numpy as np
import pytest

from repro.bench.retrieval import time_search
from repro.errors import ReproError, RetrievalError
from repro.motion.search.retrieval import MAX_QUERIES, MotionRetriever
from tests.helpers import refusal_failures


def test_time_search_reports_latencies(synthetic_db):
    db = synthetic_db
    small = db.select(np.arange(0, db.n_clips, 3))
    res = time_search(small, n_queries=8, seed=0, repeats=1, k=4)
    assert res["n_clips"] == small.n_clips and res["k"] <= 4
    for m in ("pruned", "exhaustive", "kdtree"):
        assert res["latency"][m]["p50_ms"] > 0
        assert res["latency"][m]["p99_ms"] >= res["latency"][m]["p50_ms"]
    assert 0.0 <= res["agreement"]["pruned"]["differs"] <= 1.0
    assert res["agreement"]["pruned"]["mean_excess"] >= -1e-12
    assert sum(res["pruned_fallbacks"].values()) == 8


@pytest.mark.parametrize("n", [MAX_QUERIES + 1, 10**12])
def test_query_counts_are_bounded(synthetic_db, n):
    small = synthetic_db.select(np.arange(3))
    with pytest.raises(RetrievalError, match=rf"^n_queries must be an integer in 1\.\.{MAX_QUERIES}"):
        time_search(small, n, retriever=MotionRetriever(small, seed=0))


def test_bad_time_search_arguments(synthetic_db):
    """Each call raises a ReproError subclass, and nothing else."""
    punch = np.flatnonzero(synthetic_db.semantics == "punch")[:3]
    kick = np.flatnonzero(synthetic_db.semantics == "kick")[:3]
    r = MotionRetriever(synthetic_db.select(np.concatenate([punch, kick])), seed=0)
    calls = [
        ("time_search n", lambda: time_search(r.db, 0, retriever=r)),
        ("time_search repeats", lambda: time_search(r.db, 2, retriever=r, repeats=0)),
        ("time_search methods", lambda: time_search(r.db, 2, retriever=r, methods=("fast",))),
        ("time_search no methods", lambda: time_search(r.db, 2, retriever=r, methods=())),
        ("time_search retriever", lambda: time_search(r.db, 2, retriever="r")),
    ]
    failures = refusal_failures(calls, ReproError)
    assert not failures, "\n".join(failures)
