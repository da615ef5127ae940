"""``default_database`` builds each database once per process and hands out copies.

Its docstring (and the fighter's) promise "built once per process": the embedded set is 75
BVH files written and read back (~4 s), which every motion figure, benchmark and panel asks
for.  A shared build must not be shared state: each caller gets its own copy.
"""

from __future__ import annotations

import numpy as np

from repro.motion.database import sources


def test_the_synthetic_database_is_generated_once_per_process(monkeypatch):
    # forget this process's builds, if any (the new one is kept for the tests that follow)
    sources._DEFAULT_DATABASES.clear()
    real, calls = sources.synthetic_database, []

    def counting(*args, **kwargs):
        calls.append(kwargs.get("seed"))
        return real(*args, **kwargs)

    monkeypatch.setattr(sources, "synthetic_database", counting)
    a = sources.default_database("synthetic")
    b = sources.default_database("synthetic")
    assert calls == [0]
    assert a is not b and a.n_clips == b.n_clips == 72
    np.testing.assert_array_equal(a.pose_points, b.pose_points)


def test_a_caller_changing_its_copy_does_not_change_the_next_callers():
    a = sources.default_database("synthetic")
    names, first = a.names.copy(), a.pose_points[0].copy()
    a.names[:] = "changed"
    a.pose_points[0] += 1.0
    a.meta["changed"] = True
    a.actors.clear()
    b = sources.default_database("synthetic")
    np.testing.assert_array_equal(b.names, names)
    np.testing.assert_array_equal(b.pose_points[0], first)
    assert "changed" not in b.meta and b.actors


def test_synthetic_sources_name_the_generated_set_not_a_removed_folder():
    import os

    from repro.motion.database.sources import default_database

    db = default_database("synthetic")
    assert all(s.startswith("synthetic/seed0/") and s.endswith(".bvh") for s in db.sources.tolist())
    assert not any(os.path.isabs(s) for s in db.sources.tolist())
    assert default_database("synthetic").sources.tolist() == db.sources.tolist()  # stable across calls
