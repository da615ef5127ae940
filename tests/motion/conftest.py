"""Fixtures shared by the motion tests (the session's databases are in tests/conftest.py)."""

from __future__ import annotations

import copy

import pytest


@pytest.fixture(scope="session")
def synthetic_retriever(_synthetic_db):
    """``MotionRetriever(synthetic database, seed=0)``, built once per session on its own copy of the
    database (``synthetic_retriever.db``): what the search tests share."""
    from repro.motion.search.retrieval import MotionRetriever

    return MotionRetriever(copy.deepcopy(_synthetic_db), seed=0)
