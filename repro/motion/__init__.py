"""Motion capture for Pronost et al., "Interactive Animation of Virtual Characters:
Application to Virtual Kung-fu Fighting" (about 2008).

The paper's motion database (Section 3.2) holds motion-capture clips "stored in the BVH
standard format"; this package reads and writes them.

- :mod:`~repro.motion.core.motion`: the :class:`Motion` type (skeleton, local rotations as
  quaternions, position channels) and vectorised forward kinematics; units
  (:data:`CMU_UNIT_M`, :data:`BANDAI_UNIT_M`).
- :mod:`~repro.motion.io.bvh`: :func:`read_bvh`, :func:`write_bvh` (atomic, never
  overwrites an existing file unless ``overwrite=True``).
- :mod:`~repro.motion.io.asfamc`: the Acclaim ASF/AMC originals of the CMU database,
  :func:`read_asf`, :func:`read_amc`, :func:`read_asf_amc`, converted with the same
  convention as the staged CMU BVH files.

Every malformed file raises :class:`BVHError` (a :class:`repro.errors.ReproError` and a
:class:`ValueError`) naming the line or field.
"""

from repro.errors import BVHError
from repro.motion.io.asfamc import AsfBone, AsfSkeleton, read_amc, read_asf, read_asf_amc
from repro.motion.io.bvh import read_bvh, write_bvh
from repro.motion.core.motion import BANDAI_UNIT_M, CMU_UNIT_M, Motion

__all__ = [
    "Motion",
    "read_bvh",
    "write_bvh",
    "read_asf",
    "read_amc",
    "read_asf_amc",
    "AsfSkeleton",
    "AsfBone",
    "BVHError",
    "CMU_UNIT_M",
    "BANDAI_UNIT_M",
]

# Roles, skeletons, sizes (Eq. 1), the morphology-independent representation of
# Kulpa et al. 2005 used for retargeting (Section 3.4.1) and the feet.
from repro.motion.body.roles import ROLES, find_roles  # noqa: E402
from repro.motion.body.skeleton import (  # noqa: E402
    Skeleton,
    rescale_constraint,
    scale_skeleton,
    skeleton_of,
)
from repro.motion.retargeting.morphology import (  # noqa: E402
    MorphologyIndependentMotion,
    decode,
    encode,
    naive_retarget,
    retarget,
)
from repro.motion.body.feet import foot_contacts, foot_metrics  # noqa: E402

__all__ += [
    "ROLES",
    "Skeleton",
    "find_roles",
    "rescale_constraint",
    "scale_skeleton",
    "skeleton_of",
    "MorphologyIndependentMotion",
    "encode",
    "decode",
    "retarget",
    "naive_retarget",
    "foot_contacts",
    "foot_metrics",
]

# Synthetic kung-fu database (no downloaded data needed): repro.motion.database.synthetic
from repro.motion.database.synthetic import (  # noqa: E402
    SyntheticDatabase,
    read_manifest,
    synthetic_clip,
    synthetic_database,
    synthetic_skeleton,
)

__all__ += [
    "synthetic_clip",
    "synthetic_database",
    "synthetic_skeleton",
    "read_manifest",
    "hit_point_trajectory",
    "SyntheticDatabase",
]

# The annotated motion database (Section 3.2), pose clustering (Section 3.2.2) and the
# motion retrieval (Section 3.3): repro.motion.database.annotation, .database, .sources, .augment,
# repro.motion.search.distance, .kmeans, .retrieval
from repro.motion.search.distance import AlignedPoseIndex, aligned_distance  # noqa: E402
from repro.motion.search.kmeans import PoseClusters, cluster_poses  # noqa: E402
from repro.motion.database.annotation import Hit, detect_hits, hit_point_trajectory  # noqa: E402
from repro.motion.database.augment import augment  # noqa: E402
from repro.motion.database.clips import Clip, MotionDatabase  # noqa: E402
from repro.motion.database.sources import build_cmu_database, build_database  # noqa: E402
from repro.motion.search.retrieval import MotionRetriever, RetrievalResult  # noqa: E402

__all__ += [
    "aligned_distance",
    "AlignedPoseIndex",
    "cluster_poses",
    "PoseClusters",
    "Clip",
    "Hit",
    "MotionDatabase",
    "build_database",
    "build_cmu_database",
    "detect_hits",
    "augment",
    "MotionRetriever",
    "RetrievalResult",
]

# Section 3.4.2: the constraints solver (d(t), limb IK, CCD, feet kept planted).
from repro.motion.adaptation import (  # noqa: E402
    AdaptOptions,
    Adaptation,
    CCDSolution,
    LimbSolution,
    adapt,
    ccd,
    offset_curve,
    reach_limb,
)

__all__ += [
    "offset_curve",
    "reach_limb",
    "ccd",
    "adapt",
    "AdaptOptions",
    "Adaptation",
    "LimbSolution",
    "CCDSolution",
]

# One order carried out (Sections 3.3-3.4): the Strike of repro.motion.runtime.strike.strike (the
# function itself stays on its module: a package attribute named like the submodule would shadow it).
from repro.motion.runtime.strike import Strike  # noqa: E402

__all__ += ["Strike"]

# The other real sources of the database (Bandai Namco strikes, non-fighting takes).
from repro.motion.database.sources import build_bandai_database, build_real_database, non_fighting_poses  # noqa: E402

__all__ += ["build_bandai_database", "build_real_database", "non_fighting_poses"]
