"""The exhaustive baseline (repro.motion.search.exhaustive).

What is asserted: the exhaustive search equals an independent brute-force evaluation of
``d = w_q d_qr + w_c d_cr`` (plain :func:`aligned_distance`, a loop over clips).
"""

from __future__ import annotations

import pytest

from tests.motion.search.queries import brute_force, queries


def test_exhaustive_equals_brute_force(db, retriever):
    for c, pose, ch, sem in queries(db, 4, seed=2):
        r = retriever.search_exhaustive(c, pose, ch, sem)
        d, p = brute_force(db, c, pose, ch, sem)
        assert r.d == pytest.approx(d, rel=1e-6, abs=1e-7)
        assert r.d == pytest.approx(r.w_q * r.d_qr + r.w_c * r.d_cr, rel=1e-12)
        assert r.pose == p or r.d == pytest.approx(d, abs=1e-9)
