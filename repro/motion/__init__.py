"""Pronost, Li, Geng, Multon, Kulpa, Dumont, "Interactive Animation of Virtual Characters:
Application to Virtual Kung-fu Fighting" (about 2008), as its pipeline.

Each subpackage is one stage of the paper; a stage imports only the stages above it in this
list (``tests/test_structure.py`` checks it), so data flows down the folder tree:

- :mod:`~repro.motion.core`: the :class:`Motion` type (joint tree, local rotations as
  quaternions, root positions), quaternions, the one forward kinematics, operations on
  clips (cut, resample, mirror, easing), the bounded cache.
- :mod:`~repro.motion.io`: motion files, Section 3.2's "BVH standard format"
  (:func:`read_bvh`, :func:`write_bvh`) and the CMU database's Acclaim ASF/AMC originals.
- :mod:`~repro.motion.body`: the body a motion drives: joint roles from names or structure
  (:func:`find_roles`), the :class:`Skeleton` and its size (Eq. 1's ``size_a``, ``size_c``),
  units and up axis, the rest pose, pose frames and pose clouds, the feet, where a strike lands
  (the hit point: an End Site, else the knuckles).
- :mod:`~repro.motion.retargeting`: Section 3.4.1, Kulpa et al.'s morphology-independent
  representation (:func:`encode`, :func:`decode`, :func:`retarget`), retargeting across
  joint trees through the roles, one dispatcher between the two.
- :mod:`~repro.motion.database`: Section 3.2, the annotated clips (:class:`MotionDatabase`,
  :func:`detect_hits`), the real sources (CMU, Bandai Namco), augmentation, the synthetic
  database a fresh clone runs on.
- :mod:`~repro.motion.search`: Sections 3.2.2-3.3, Kovar's aligned pose distance, k-means of
  poses, the paper's pruned search by Eq. 1 and the exact branch and bound
  (:class:`MotionRetriever`).
- :mod:`~repro.motion.adaptation`: Section 3.4.2, the offset ``d(t)``, limb IK, CCD, the
  feet kept planted (:func:`adapt`).
- :mod:`~repro.motion.runtime`: one order carried out, retrieve -> retarget -> adapt
  (:func:`repro.motion.runtime.strike.strike`, :class:`Strike`) as :class:`StrikeOptions` say
  (the library's defaults; :data:`PAPER` the paper's choices), and the interactive fighter,
  with the paper's constants.

The names below are the public API the figures, benchmarks and panels use; the rest is
reachable through the stage modules. Every malformed file raises :class:`BVHError`, every bad
argument a :class:`repro.errors.ReproError` naming the value and what was expected.
"""

from repro.errors import BVHError

# core: the Motion type and its units
from repro.motion.core.motion import BANDAI_UNIT_M, CMU_UNIT_M, Motion

# io: BVH, and the CMU database's ASF/AMC originals
from repro.motion.io.asf import AsfBone, AsfSkeleton, read_asf
from repro.motion.io.asfamc import read_amc, read_asf_amc
from repro.motion.io.bvh import read_bvh, write_bvh

# body: roles, the Skeleton and its sizes (Eq. 1), the feet
from repro.motion.body.feet import foot_contacts, foot_metrics
from repro.motion.body.roles import ROLES, find_roles
from repro.motion.body.skeleton import Skeleton, rescale_constraint, scale_skeleton, skeleton_of

# retargeting (Section 3.4.1): Kulpa et al.'s morphology-independent representation
from repro.motion.retargeting.morphology import MorphologyIndependentMotion, decode, encode, naive_retarget, retarget

# database (Section 3.2): annotated clips, their sources, augmentation, the synthetic database
from repro.motion.database.annotation import Hit, detect_hits, hit_point_trajectory
from repro.motion.database.augment import augment
from repro.motion.database.clips import Clip, MotionDatabase
from repro.motion.database.sources import (
    build_bandai_database,
    build_cmu_database,
    build_database,
    build_real_database,
    non_fighting_poses,
)
from repro.motion.database.synthetic import (
    SyntheticDatabase,
    read_manifest,
    synthetic_clip,
    synthetic_database,
    synthetic_skeleton,
)

# search (Sections 3.2.2-3.3): the aligned pose distance, k-means, the retriever
from repro.motion.search.distance import AlignedPoseIndex, aligned_distance
from repro.motion.search.kmeans import PoseClusters, cluster_poses
from repro.motion.search.retrieval import MotionRetriever, RetrievalResult

# adaptation (Section 3.4.2): d(t), limb IK, CCD, the whole edit
from repro.motion.adaptation import (
    AdaptOptions,
    Adaptation,
    CCDSolution,
    LimbSolution,
    adapt,
    ccd,
    offset_curve,
    reach_limb,
)

# runtime (Sections 3.3-3.4): one order carried out.  The function strike stays on its module
# (repro.motion.runtime.strike.strike): a package attribute named like the submodule would shadow it.
from repro.motion.runtime.options import StrikeOptions
from repro.motion.runtime.paper import PAPER
from repro.motion.runtime.strike import Strike

__all__ = [
    "BVHError",
    # core
    "Motion", "CMU_UNIT_M", "BANDAI_UNIT_M",
    # io
    "read_bvh", "write_bvh", "read_asf", "read_amc", "read_asf_amc", "AsfSkeleton", "AsfBone",
    # body
    "ROLES", "find_roles", "Skeleton", "skeleton_of", "scale_skeleton", "rescale_constraint",
    "foot_contacts", "foot_metrics",
    # retargeting
    "MorphologyIndependentMotion", "encode", "decode", "retarget", "naive_retarget",
    # database
    "Clip", "MotionDatabase", "Hit", "detect_hits", "hit_point_trajectory", "augment",
    "build_database", "build_cmu_database", "build_bandai_database", "build_real_database",
    "non_fighting_poses", "SyntheticDatabase", "synthetic_clip", "synthetic_database",
    "synthetic_skeleton", "read_manifest",
    # search
    "aligned_distance", "AlignedPoseIndex", "cluster_poses", "PoseClusters", "MotionRetriever",
    "RetrievalResult",
    # adaptation
    "AdaptOptions", "adapt", "Adaptation", "offset_curve", "reach_limb", "LimbSolution", "ccd",
    "CCDSolution",
    # runtime
    "Strike", "StrikeOptions", "PAPER",
]
