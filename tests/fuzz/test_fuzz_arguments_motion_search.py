"""Argument fuzzer cases of the motion database and its search (issue 23, sections 3, 5, 6, 8).

The database (:class:`repro.motion.database.clips.MotionDatabase`'s accessors, ``select``,
``from_clips``, :class:`~repro.motion.database.clips.Clip`, ``annotate``), its builders and
variants (:mod:`repro.motion.database.sources`, :func:`repro.motion.database.augment.augment`), the
annotation (:mod:`repro.motion.database.annotation`), the retrieval (:class:`MotionRetriever` and its
searches, :func:`make_queries`, :func:`time_search`, the retargeting helpers), the pose
clouds, their distance and their clustering (:mod:`repro.motion.body.pose_frames`, :mod:`repro.motion.search.distance`,
:mod:`repro.motion.search.kmeans`), the exact search's public
helpers (:mod:`repro.motion.search.exact`), the synthetic generator and the BVH writer:
every parameter gets the hostile values of :mod:`tests.fuzz.arguments` (a ReproError or a
finite result, never another exception, a hang or an allocation past the budget).

The database (6 clips of the synthetic one) and its retriever are built once per child
(:func:`functools.cache`); searches use ``method="pruned"`` or the exhaustive search (no numba
compile in the child).  Not fuzzed: the compiled kernel (:mod:`repro.motion.search.kernel`,
called with arrays the checked entries made) and the quaternion helpers
(:mod:`repro.motion.core.quaternion`, the solvers' inner arithmetic on checked arrays, as the
kinematics helpers in the runtime cases); the file readers have their own fuzzer.
"""

from __future__ import annotations

import functools

import numpy as np
import pytest

from tests.fuzz.arguments import Case, check

pytestmark = pytest.mark.fuzz

#: Seconds per call of the cases that build something on their first call.
SLOW = 120.0


# ------------------------------------------------------------------ shared fixtures (once per child)
@functools.cache
def _tmp() -> str:
    """One temporary folder per child for what the cases write, removed when the child exits."""
    import atexit
    import shutil
    import tempfile

    d = tempfile.mkdtemp(prefix="fuzz-motion-search-")
    atexit.register(shutil.rmtree, d, ignore_errors=True)
    return d


@functools.cache
def _full():
    from repro.motion.database.sources import default_database

    return default_database("synthetic")


@functools.cache
def _db():
    full = _full()
    punch = np.flatnonzero(full.semantics == "punch")[:3]
    kick = np.flatnonzero(full.semantics == "kick")[:3]
    return full.select(np.concatenate([punch, kick]))


@functools.cache
def _retriever():
    from repro.motion.search.retrieval import MotionRetriever

    return MotionRetriever(_db(), seed=0)


@functools.cache
def _pose():
    from repro.motion.runtime.strike import one_frame

    return one_frame(_db().motion(0), 0)


@functools.cache
def _character():
    return _db().actor_skeleton(0)


@functools.cache
def _clip():
    return _db().clip(0)


@functools.cache
def _points():
    return np.random.default_rng(0).normal(size=(60, 6, 3))


@functools.cache
def _global():
    return _clip().motion.global_positions()


@functools.cache
def _synthetic_dir():
    import tempfile

    from repro.motion.database.synthetic import synthetic_database

    d = tempfile.mkdtemp(dir=_tmp(), prefix="fuzz-synthetic-")
    synthetic_database(d, n_actors=1, seed=0)
    return d


TARGET = [0.3, 1.4, 0.5]


# ------------------------------------------------------------------ the database
def _db_method(name, **kw):
    return lambda: (getattr(_db(), name), dict(kw))


def _from_clips():
    from repro.motion.database.clips import MotionDatabase

    return MotionDatabase.from_clips, dict(clips=[_clip()], window=1, step=1, meta={"a": 1})


def _clip_ctor():
    from repro.motion.database.clips import Clip

    c = _clip()
    return Clip, dict(name="n", motion=c.motion, semantics=c.semantics, hit_role=c.hit_role, hit_joint=c.hit_joint,
                      hit_where=c.hit_where, hit_frame=c.hit_frame, kind="k", side=c.side, source="s",
                      source_time=0.0, level="")


def _annotate():
    from repro.motion.database.clips import annotate

    c = _clip()
    return annotate, dict(motion=c.motion, hit_frame=c.hit_frame, hit_role=c.hit_role, semantics=c.semantics,
                          name="n", hit_joint=None, hit_where="joint")


def _augment():
    from repro.motion.database.augment import augment

    return augment, dict(db=_db(), factor=2, seed=0, scale_range=(0.85, 1.15), warp_range=(0.85, 1.15), noise=0.005,
                         mirror_probability=0.5, pose_dtype=None)


def _default_database():
    from repro.motion.database.sources import default_database

    return default_database, dict(name="synthetic", seed=0)


def _build_database():
    from repro.motion.database.sources import build_database

    return build_database, dict(source=_synthetic_dir(), fps=30.0, window=None, unit_m=None, manifest="manifest.csv",
                                pose_window=1, detect_kw=None)


def _clip_source_dataset():
    from repro.motion.database.sources import clip_source_dataset

    return clip_source_dataset, dict(db=_db())


# ------------------------------------------------------------------ annotation
def _detect_hits():
    from repro.motion.database.annotation import detect_hits

    return detect_hits, dict(motion=_clip().motion, skeleton=None, semantics=None, side=None)


def _hit_frame_for():
    from repro.motion.database.annotation import hit_frame_for

    return hit_frame_for, dict(motion=_clip().motion, role=_clip().hit_role, skeleton=None)


def _check_semantics():
    from repro.motion.database.annotation import check_semantics

    return check_semantics, dict(s="punch")


def _hit_point_trajectory():
    from repro.motion.database.annotation import hit_point_trajectory

    c = _clip()
    return hit_point_trajectory, dict(motion=c.motion, joint=c.hit_joint, where="joint", positions=None)


# ------------------------------------------------------------------ retrieval
def _retriever_ctor():
    from repro.motion.search.retrieval import MotionRetriever

    return MotionRetriever, dict(db=_db(), k=None, seed=0, weights=None, w_q=1.0, w_c=1.0, kd_neighbours=32,
                                 across_trees=True)


def _search():
    return _retriever().search, dict(target=TARGET, current_pose=_pose(), character=_character(), semantics="punch",
                                     prune=True, scale_target=True, frame=None, method="pruned")


def _search_exhaustive():
    return _retriever().search_exhaustive, dict(target=TARGET, current_pose=_pose(), character=_character(),
                                                semantics="kick", scale_target=True, frame=None)


def _search_kdtree():
    return _retriever().search_kdtree, dict(target=TARGET, current_pose=_pose(), character=_character(),
                                            semantics="punch", frame=None)


def _prepare():
    return _retriever().prepare, dict(current_pose=_pose(), character=_character(), frame=None)


@functools.cache
def _result():
    return _retriever().search(TARGET, _pose(), _character(), "punch")


def _result_align():
    return _result().align, dict(points=np.zeros((4, 3)))


def _result_place():
    return _result().place, dict(points=np.zeros((4, 3)), scale=None)


def _make_queries():
    from repro.motion.search.retrieval import make_queries

    return make_queries, dict(db=_db(), n=2, seed=0, noise=0.05)


def _time_search():
    from repro.bench.retrieval import time_search

    return time_search, dict(db=_db(), n_queries=2, seed=0, retriever=_retriever(), methods=("pruned",), repeats=1,
                             noise=0.05)


def _character_skeleton():
    from repro.motion.retargeting.dispatch import character_skeleton

    return character_skeleton, dict(character=_character(), purposes=("a punch",))


def _rest_motion_y_up():
    from repro.motion.retargeting.dispatch import rest_motion_y_up

    return rest_motion_y_up, dict(character=_character())


def _retarget_to_tree():
    from repro.motion.retargeting.dispatch import retarget_to_tree

    return retarget_to_tree, dict(motion=_db().motion(1), character=_character(), roles=None, target=None,
                                  fix_feet=False)


# ------------------------------------------------------------------ pose clouds and clustering
def _clustering(name, **kw):
    def setup():
        from repro.motion.body import pose_frames
        from repro.motion.search import distance, kmeans

        module = next(m for m in (pose_frames, distance, kmeans) if hasattr(m, name))
        return getattr(module, name), {k: (v() if callable(v) else v) for k, v in kw.items()}

    return setup


@functools.cache
def _index():
    from repro.motion.search.distance import AlignedPoseIndex

    return AlignedPoseIndex(_points())


def _index_method(name, **kw):
    return lambda: (getattr(_index(), name), {k: (v() if callable(v) else v) for k, v in kw.items()})


def _exact(name, **kw):
    def setup():
        import repro.motion.search.exact as ex

        return getattr(ex, name), {k: (v() if callable(v) else v) for k, v in kw.items()}

    return setup


# ------------------------------------------------------------------ synthetic data and BVH writing
def _synthetic_clip():
    from repro.motion.database.synthetic import synthetic_clip

    return synthetic_clip, dict(kind="punch", side="right", level="middle", actor_height=1.75, seed=0, fps=30.0)


def _synthetic_skeleton():
    from repro.motion.database.synthetic import synthetic_skeleton

    return synthetic_skeleton, dict(actor_height=1.75)


def _database_actor_heights():
    from repro.motion.database.synthetic import database_actor_heights

    return database_actor_heights, dict(n_actors=3)


def _conventions_build():
    from repro.motion.database.synthetic.conventions import build

    return build, dict(convention="mixamo", height=1.75)


def _write_bvh():
    import tempfile

    from repro.motion.io.bvh import write_bvh

    return write_bvh, dict(motion=_clip().motion, path=tempfile.mkdtemp(dir=_tmp(), prefix="fuzz-bvh-") + "/a.bvh",
                           overwrite=False, precision=12)


def _retarget_plan():
    return _retriever().retarget_plan, dict(m=_pose(), a=0)


def _tree_plan():
    from repro.motion.body.roles import find_roles

    m = _pose()
    return _retriever().tree_plan, dict(m=m, a=0, roles=find_roles(list(m.joint_names), m.parents, offsets=m.offsets))


def _load_or_build():
    import tempfile

    from repro.motion.database.sources import load_or_build

    return load_or_build, dict(path=tempfile.mkdtemp(dir=_tmp(), prefix="fuzz-db-") + "/db.npz", build=_db)


def _synthetic_database():
    import tempfile

    from repro.motion.database.synthetic import synthetic_database

    return synthetic_database, dict(out_dir=tempfile.mkdtemp(dir=_tmp(), prefix="fuzz-syn-"), n_actors=1, seed=0, fps=30.0,
                                    overwrite=False)


def _read_manifest():
    import os

    from repro.motion.database.synthetic import read_manifest

    return read_manifest, dict(path=os.path.join(_synthetic_dir(), "manifest.csv"), verify=False)


def _expected_roles():
    from repro.motion.database.synthetic.conventions import expected_roles

    return expected_roles, dict(convention="smpl")


def _read_bvh():
    import os

    from repro.motion.io.bvh import read_bvh

    d = _synthetic_dir()
    return read_bvh, dict(src=os.path.join(d, sorted(f for f in os.listdir(d) if f.endswith(".bvh"))[0]),
                          unit_m=None, strict=False)


CASES = [
    # the database
    *[Case(f"MotionDatabase.{m}", _db_method(m, i=1), {"i": "index"}, time_limit=SLOW)
      for m in ("motion", "clip", "trajectory", "poses_of", "actor_skeleton")],
    Case("MotionDatabase.select", _db_method("select", mask=[0, 2]), {"mask": "index_array"}, time_limit=SLOW),
    Case("MotionDatabase.from_clips", _from_clips,
         {"clips": "any", "pose_roles": "array", "window": "int", "step": "int", "meta": "mapping"}, time_limit=SLOW),
    Case("Clip", _clip_ctor,
         {"name": "str", "motion": "any", "semantics": "choice", "hit_role": "choice", "hit_joint": "str",
          "hit_where": "choice", "hit_frame": "index", "kind": "str", "side": "choice", "source": "str",
          "source_time": "real", "level": "str"}, time_limit=SLOW),
    Case("annotate", _annotate,
         {"motion": "any", "hit_frame": "index", "hit_role": "choice", "semantics": "choice", "name": "str",
          "hit_joint": "str", "hit_where": "choice"}, time_limit=SLOW),
    Case("augment", _augment,
         {"db": "any", "factor": "int", "seed": "int", "scale_range": "array", "warp_range": "array", "noise": "real",
          "mirror_probability": "real", "pose_dtype": "any"}, time_limit=SLOW),
    Case("default_database", _default_database, {"name": "choice", "seed": "int"}, time_limit=SLOW),
    Case("build_database", _build_database,
         {"source": "path", "fps": "real", "window": "array", "unit_m": "real", "manifest": "path",
          "pose_window": "int", "detect_kw": "mapping"}, time_limit=SLOW),
    Case("clip_source_dataset", _clip_source_dataset, {"db": "any"}, time_limit=SLOW),
    # annotation
    Case("detect_hits", _detect_hits,
         {"motion": "any", "skeleton": "any", "semantics": "choice", "side": "choice", "arm_extension": "real",
          "arm_front": "real", "kick_height": "real", "leg_extension": "real", "merge_gap": "real",
          "min_duration": "real", "peak_tolerance": "real"}, time_limit=SLOW),
    Case("hit_frame_for", _hit_frame_for, {"motion": "any", "role": "choice", "skeleton": "any"}, time_limit=SLOW),
    Case("check_semantics", _check_semantics, {"s": "choice"}),
    Case("hit_point_trajectory", _hit_point_trajectory,
         {"motion": "any", "joint": "str", "where": "choice", "positions": "array"}, time_limit=SLOW),
    # retrieval
    Case("MotionRetriever", _retriever_ctor,
         {"db": "any", "k": "int", "seed": "int", "weights": "array", "w_q": "real", "w_c": "real",
          "kd_neighbours": "int", "across_trees": "bool"}, time_limit=SLOW,
         nonfinite_ok={"radius"}),  # a cluster without poses of a semantics has an infinite radius (documented)
    Case("MotionRetriever.search", _search,
         {"target": "array", "current_pose": "any", "character": "any", "semantics": "choice", "prune": "bool",
          "scale_target": "bool", "frame": "index", "method": "choice"}, time_limit=SLOW),
    Case("MotionRetriever.search_exhaustive", _search_exhaustive,
         {"target": "array", "current_pose": "any", "character": "any", "semantics": "choice",
          "scale_target": "bool", "frame": "index"}, time_limit=SLOW),
    Case("MotionRetriever.search_kdtree", _search_kdtree,
         {"target": "array", "current_pose": "any", "character": "any", "semantics": "choice", "frame": "index"},
         time_limit=SLOW),
    Case("MotionRetriever.prepare", _prepare, {"current_pose": "any", "character": "any", "frame": "index"},
         time_limit=SLOW),
    Case("RetrievalResult.align", _result_align, {"points": "array"}, time_limit=SLOW),
    Case("RetrievalResult.place", _result_place, {"points": "array", "scale": "real"}, time_limit=SLOW),
    Case("make_queries", _make_queries, {"db": "any", "n": "int", "seed": "int", "noise": "real"}, time_limit=SLOW),
    Case("time_search", _time_search,
         {"db": "any", "n_queries": "int", "seed": "int", "retriever": "any", "methods": "array", "repeats": "int",
          "noise": "real"}, time_limit=SLOW),
    Case("character_skeleton", _character_skeleton, {"character": "any", "purposes": "array"}, time_limit=SLOW),
    Case("rest_motion_y_up", _rest_motion_y_up, {"character": "any"}, time_limit=SLOW),
    Case("retarget_to_tree", _retarget_to_tree,
         {"motion": "any", "character": "any", "roles": "mapping", "target": "any", "fix_feet": "bool"},
         time_limit=SLOW),
    # pose clouds and clustering
    Case("rotate_y", _clustering("rotate_y", points=lambda: _points()[0], theta=0.3),
         {"points": "array", "theta": "array"}),
    Case("heading_from_hips", _clustering("heading_from_hips", left_hip=lambda: _points()[:, 0],
                                          right_hip=lambda: _points()[:, 1]),
         {"left_hip": "array", "right_hip": "array"}),
    Case("root_frames", _clustering("root_frames", global_positions=_global, pelvis=0, left_hip=1, right_hip=5),
         {"global_positions": "array", "pelvis": "index", "left_hip": "index", "right_hip": "index"}, time_limit=SLOW),
    Case("to_root_frame", _clustering("to_root_frame", points=lambda: _points()[0], theta=0.2, origin=np.zeros(3)),
         {"points": "array", "theta": "array", "origin": "array"}),
    Case("from_root_frame", _clustering("from_root_frame", points=lambda: _points()[0], theta=0.2,
                                        origin=np.zeros(3)),
         {"points": "array", "theta": "array", "origin": "array"}),
    Case("pose_points", _clustering("pose_points", global_positions=_global, joints=[2, 3], pelvis=0, left_hip=1,
                                    right_hip=5, window=1, step=1, first=None),
         {"global_positions": "array", "joints": "index_array", "pelvis": "index", "left_hip": "index",
          "right_hip": "index", "window": "int", "step": "int", "first": "index_array"}, time_limit=SLOW),
    Case("pose_weights", _clustering("pose_weights", n_points=6, weights=None), {"n_points": "int", "weights": "array"}),
    Case("aligned_distance", _clustering("aligned_distance", a=lambda: _points()[0], b=lambda: _points()[1],
                                         weights=None, return_transform=False),
         {"a": "array", "b": "array", "weights": "array", "return_transform": "bool"}),
    Case("AlignedPoseIndex", _clustering("AlignedPoseIndex", points=_points, weights=None, order=None),
         {"points": "array", "weights": "array", "order": "index_array"}),
    Case("AlignedPoseIndex.distances", _index_method("distances", q=lambda: _points()[0], rows=None,
                                                     return_transform=False),
         {"q": "array", "rows": "index_array", "return_transform": "bool"}),
    Case("AlignedPoseIndex.direct_distance", _index_method("direct_distance", q=lambda: _points()[0], row=3),
         {"q": "array", "row": "index"}),
    Case("AlignedPoseIndex.subset", _index_method("subset", rows=[0, 2]), {"rows": "index_array"}),
    Case("AlignedPoseIndex.centroids_xz", _index_method("centroids_xz", rows=None), {"rows": "index_array"}),
    Case("AlignedPoseIndex.query_matrix", _index_method("query_matrix", q=lambda: _points()[0]), {"q": "array"}),
    Case("cluster_poses", _clustering("cluster_poses", points=_points, k=3, weights=None, seed=0, iterations=20,
                                      max_fit=20000),
         {"points": "array", "k": "int", "weights": "array", "seed": "int", "iterations": "int", "max_fit": "int"}),
    Case("default_k", _clustering("default_k", n_poses=100), {"n_poses": "int"}),
    Case("sample_grid", _exact("sample_grid", pts=lambda: _points()[:, 0], per_cell=8, max_cells=1 << 21),
         {"pts": "array", "per_cell": "int", "max_cells": "int"}),
    # synthetic data, BVH writing
    Case("synthetic_clip", _synthetic_clip,
         {"kind": "choice", "side": "choice", "level": "choice", "actor_height": "real", "seed": "int", "fps": "real"},
         time_limit=SLOW),
    Case("synthetic_skeleton", _synthetic_skeleton, {"actor_height": "real"}),
    Case("database_actor_heights", _database_actor_heights, {"n_actors": "int"}),
    Case("conventions.build", _conventions_build, {"convention": "choice", "height": "real"}),
    # the path is a fresh temporary file: a hostile path paired with overwrite=True would write over a
    # file of the machine (the hostile paths include ../../../../etc/passwd)
    Case("MotionRetriever.retarget_plan", _retarget_plan, {"m": "any", "a": "index"}, time_limit=SLOW),
    Case("MotionRetriever.tree_plan", _tree_plan, {"m": "any", "a": "index", "roles": "mapping"}, time_limit=SLOW),
    Case("load_or_build", _load_or_build, {"build": "callable"}, time_limit=SLOW),
    Case("synthetic_database", _synthetic_database,
         {"n_actors": "int", "seed": "int", "fps": "real", "overwrite": "bool"}, time_limit=SLOW),
    Case("read_manifest", _read_manifest, {"verify": "bool"}, time_limit=SLOW),
    Case("expected_roles", _expected_roles, {"convention": "choice"}),
    Case("read_bvh", _read_bvh, {"unit_m": "real", "strict": "bool"}, time_limit=SLOW),
    Case("write_bvh", _write_bvh, {"motion": "any", "overwrite": "bool", "precision": "int"}, time_limit=SLOW),
]


def test_motion_search_arguments(tmp_path):
    check(__name__, log_dir=str(tmp_path))
