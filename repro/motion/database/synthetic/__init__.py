"""A synthetic kung-fu motion database, generated without any downloaded data.

Pronost et al., "Interactive Animation of Virtual Characters: Application to Virtual
Kung-fu Fighting", Section 3.2 ("Design of the database"), build their motion database
from about 75 motion-captured kung-fu moves (punches and kicks) stored as BVH files,
each annotated with the hit segment (e.g. the right hand or the left foot), the
semantics (punching or kicking), the hit time and the trajectory of the hit point with
its bounding box.  Those captures are not available, so this package *synthesises* a
database of the same shape: an actor performing straight punches and front, side and
round kicks with either side at three target heights, plus a few idle fighting-stance
clips, written as BVH files with a ``manifest.csv`` holding the annotations.

What is synthetic
-----------------
Everything.  The clips are procedural keyframe animation, not motion capture: a
hand-designed timeline (fighting stance, wind-up or knee chamber, strike, hit, recoil,
back to the stance) whose timing, amplitudes, stance dimensions, guard, target height
and hit flexion are drawn from a seeded :class:`numpy.random.Generator`, so the same
seed gives byte-identical files.  The clips have none of the subtleties of captured
motion (no noise, no secondary motion, no balance dynamics).  They exist so that the
BVH -> annotated database -> retrieval -> adaptation pipeline of the paper runs end to
end without data, and so that its tests have data with *known* ground truth (hit frame,
hit joint, target height, planted feet).

What "plausible" means here (each property is checked by the tests)
-------------------------------------------------------------------
* **Skeleton**: 21 joints with Mixamo/cgspeed names (:data:`JOINT_NAMES`), metres,
  Y up, the actor facing +Z in the rest pose (a T-pose) with +X on the actor's left;
  human proportions scaled uniformly with the actor height (:func:`synthetic_skeleton`).
* **Smoothness**: every degree of freedom is a keyframe track interpolated with
  ease curves whose slope vanishes at the keys (quintic smootherstep, C2; the strike
  segment uses ``5u^4 - 4u^5``, C1), so positions and rotations are continuous with
  continuous velocity; directions are slerped, rotations blended by quaternion slerp.
* **Joint limits**: elbows and knees are hinges: their local rotation is a single
  rotation about a fixed axis (:data:`HINGE_AXES`) by a flexion angle within
  :data:`ELBOW_FLEXION_LIMITS_DEG` / :data:`KNEE_FLEXION_LIMITS_DEG` (3 to 150
  degrees): they bend one way only and never hyperextend.  Limbs are posed by analytic
  two-bone inverse kinematics that clamps the flexion to those limits.  Other joints
  (hips, shoulders, spine, ankles, toes) are *not* range-limited; see Limitations.
* **Planted feet**: a foot on the ground is solved by leg IK to a fixed world position
  and orientation, so it does not slide at all (to rounding).  Around a kick's lift-off
  and touch-down the kicking foot pivots on the ball of the foot (heel raised, ball and
  toes fixed on the ground), as real kickers do.  The root height is chosen per frame,
  smoothly, so that every planted leg reaches its foot with the knee bent by at least
  about 16 degrees (20 in double support); :func:`synthetic_clip` raises
  :class:`~repro.errors.MotionError` if a planted foot would miss its place by more
  than a micrometre.  The feet and toes stay above the ground (to about 2 mm).
* **Clear hit**: at the annotated hit frame the striking limb is extended (elbow
  flexion 6-14 degrees for punches, knee flexion 5-10 for kicks), the hit point
  (:data:`HIT_POINTS`) is at the target height of the level
  (:data:`TARGET_HEIGHT_FRACTION` of the actor height, to a micrometre) and at its
  largest distance from the shoulder or hip joint over the clip; the strike accelerates
  then decelerates into the hit, so the hit point's speed peaks a few frames (2-5 at
  60 fps) before the hit frame, at about 6-12 m/s for punches and 6-17 m/s for kicks.
  (At 30 fps a strike lasts only 4-7 frames and the sampled peak can be missed.)

Limitations
-----------
No physics: the centre of mass is moved over the support foot by design, not by a
balance model.  No hand, finger or forearm-twist animation; the head is turned 80 %
of the way towards the target.  The support foot never pivots, so in side and round
kicks the support hip twists by up to about 60 degrees relative to the foot.  Shoulder,
hip, spine and ankle rotations are not range-limited (only designed to stay moderate).
Near full extension the two-bone IK makes the knee or elbow angle change fast in the
last frames before the hit (up to about 40 degrees per frame at 60 fps).  Kicks use the
rear leg, punches the rear hand; every clip starts and ends in the same stance, and the
target is always straight ahead (+Z).

Layout
------
:mod:`.skeleton` (the actor), :mod:`.moves` (kinds, sides, target heights, semantics,
hit points), :mod:`.tracks` (keyframe tracks, easing, rotation helpers), :mod:`.ik`
(hinge-clamped two-bone IK), :mod:`.choreography` (one clip: :func:`synthetic_clip`), :mod:`.writer` (the database on disk: :func:`synthetic_database`,
:func:`read_manifest`).

Example
-------
>>> motion, ann = synthetic_clip("kick_round", "right", "high", actor_height=1.8, seed=3)
>>> ann["semantics"], ann["hit_joint"]
('kick', 'RightFoot')
"""

from repro.motion.database.synthetic.choreography import synthetic_clip
from repro.motion.database.synthetic.moves import (
    HIT_LEVELS,
    HIT_POINTS,
    KIND_SEMANTICS,
    KINDS,
    SIDES,
    STRIKE_KINDS,
    TARGET_HEIGHT_FRACTION,
)
from repro.motion.database.synthetic.skeleton import (
    DEFAULT_FPS,
    ELBOW_FLEXION_LIMITS_DEG,
    HINGE_AXES,
    JOINT_NAMES,
    KNEE_FLEXION_LIMITS_DEG,
    REFERENCE_HEIGHT_M,
    synthetic_skeleton,
)
from repro.motion.database.synthetic.writer import (
    MANIFEST_COLUMNS,
    MANIFEST_NAME,
    SyntheticDatabase,
    database_actor_heights,
    read_manifest,
    synthetic_database,
)

__all__ = [
    "KINDS",
    "STRIKE_KINDS",
    "SIDES",
    "HIT_LEVELS",
    "KIND_SEMANTICS",
    "JOINT_NAMES",
    "HINGE_AXES",
    "HIT_POINTS",
    "ELBOW_FLEXION_LIMITS_DEG",
    "KNEE_FLEXION_LIMITS_DEG",
    "TARGET_HEIGHT_FRACTION",
    "REFERENCE_HEIGHT_M",
    "DEFAULT_FPS",
    "MANIFEST_NAME",
    "MANIFEST_COLUMNS",
    "SyntheticDatabase",
    "synthetic_skeleton",
    "synthetic_clip",
    "synthetic_database",
    "database_actor_heights",
    "read_manifest",
]
