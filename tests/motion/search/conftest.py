"""The search tests' database and retriever: the session's synthetic retriever (tests/motion/conftest.py)."""

import pytest


@pytest.fixture(scope="module")
def db(synthetic_retriever):
    return synthetic_retriever.db


@pytest.fixture(scope="module")
def retriever(synthetic_retriever):
    return synthetic_retriever
