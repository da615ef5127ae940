"""Argument fuzzer cases of the motion runtime (issue 23, sections 3, 5, 6, 8).

The order pipeline (:func:`repro.motion.runtime.strike.strike` and its helpers), the fighter
(:class:`repro.motion.runtime.fighter.KungFuFighter`, :func:`~repro.motion.runtime.fighter.simulated_user`),
the constraint solver (:mod:`repro.motion.adaptation`), retargeting (:mod:`repro.motion.retargeting.morphology`,
:mod:`repro.motion.retargeting.trees`), skeletons, roles, motions and forward kinematics: every
parameter gets the hostile values of :mod:`tests.fuzz.arguments` (a ReproError or a finite
result, never another exception, a hang or an allocation past the budget).

The database, its retriever and the characters are built once per child
(:func:`functools.cache`); the fighter cases share the retriever and search with
``StrikeOptions(method="pruned")`` (no numba compile in the child).  The strike's valid target is one the
spine cannot reach, so the root level runs on the valid call and on every hostile value
the entry lets through.  The raw-array helpers of :mod:`repro.motion.core.kinematics` (``dot``,
``normalize``, ``matvec``...) are the solvers' inner arithmetic on arrays the checked entries
made, and are not fuzzed here.
"""

from __future__ import annotations

import functools

import pytest

from tests.fuzz.arguments import Case, check

pytestmark = pytest.mark.fuzz

#: Seconds per call of the cases that build the database on their first call (3-10 s on 2 cores).
SLOW = 120.0


# ------------------------------------------------------------------ shared fixtures (once per child)
@functools.cache
def _db():
    from repro.motion.database.sources import default_database

    return default_database("synthetic")


@functools.cache
def _retriever():
    from repro.motion.search.retrieval import MotionRetriever

    return MotionRetriever(_db(), seed=0)


@functools.cache
def _character():
    from repro.motion.body.skeleton import scale_skeleton

    return scale_skeleton(_db().actors[0], height=1.8)


@functools.cache
def _stance():
    from repro.motion.retargeting.morphology import retarget
    from repro.motion.runtime.strike import one_frame

    db = _db()
    names = [str(n) for n in db.names]
    return one_frame(retarget(db.motion(names.index("actor2_punch_left_high")), _character()), 0)


@functools.cache
def _clip():
    from repro.motion.database.synthetic import synthetic_clip

    return synthetic_clip("punch", seed=3)[0]


@functools.cache
def _mixamo():
    from repro.motion.database.synthetic.conventions import build

    return build("mixamo")[0].motion(unit_m=1.0)


@functools.cache
def _skeleton():
    from repro.motion.body.skeleton import skeleton_of

    return skeleton_of(_clip())


def _fighter():
    from repro.motion.runtime.fighter import KungFuFighter

    return KungFuFighter(_db(), retriever=_retriever(), options=_pruned())  # a fresh one: methods change it


# ------------------------------------------------------------------ the order pipeline
def _pruned():
    from repro.motion.runtime.options import StrikeOptions

    return StrikeOptions(method="pruned")


def _strike():
    from repro.motion.runtime.strike import strike

    return strike, dict(source=_retriever(), character=_character(), current_motion=_stance(),
                        target=[0.0, 0.9, 1.2], semantics="punch", frame="root", query=None, options=_pruned(),
                        seed=0, t_order=None)


STRIKE_PARAMS = {
    "source": "any", "character": "any", "current_motion": "any", "target": "array", "semantics": "choice",
    "frame": "choice", "query": "any", "options": "any", "seed": "int", "t_order": "real",
}


def _strike_options():
    from repro.motion.adaptation import AdaptOptions
    from repro.motion.runtime.options import StrikeOptions

    return StrikeOptions, dict(method="pruned", blend_s=0.2, fix_feet=False, reach="root", max_root_shift=0.35,
                               adapt=AdaptOptions(), early_stop=True, stream=True)


STRIKE_OPTIONS_PARAMS = {
    "method": "choice", "blend_s": "real", "fix_feet": "bool", "reach": "choice", "max_root_shift": "real",
    "adapt": "any", "early_stop": "bool", "stream": "bool",
}


def _one_frame():
    from repro.motion.runtime.strike import one_frame

    return one_frame, dict(motion=_clip(), f=0)


def _turn_and_move():
    from repro.motion.runtime.strike import turn_and_move

    return turn_and_move, dict(motion=_clip(), theta=0.3, translation=[0.1, 0.0, 0.2])


def _blend_into():
    from repro.motion.runtime.strike import blend_into

    return blend_into, dict(pose=_clip(), placed=_clip(), n_blend=3)


def _clip_effector():
    from repro.motion.runtime.strike import clip_effector

    return clip_effector, dict(db=_db(), clip=0, character=_character())


def _reach_by_distance():
    from repro.motion.runtime.strike import reach_by_distance

    return reach_by_distance, dict(distances=[0.5, 1.0, 1.5], reached=[True, True, False],
                                   levels=["limb", "root", "root"], bins=2)


# ------------------------------------------------------------------ the fighter
def _method(attr, /, **kw):
    def setup():
        return getattr(_fighter(), attr), kw

    return setup


def _fighter_ctor():
    from repro.motion.runtime.fighter import KungFuFighter

    return (lambda **kw: KungFuFighter(_db(), retriever=_retriever(), **kw),
            dict(character=None, height=1.75, arm_scale=1.0, leg_scale=1.0, seed=0, position=(0.0, -0.8),
                 heading=0.0, options=_pruned(), across_trees=None))


def _simulated_user():
    from repro.motion.runtime.fighter import simulated_user

    return simulated_user, dict(seed=0, duration=2.0, fps=30.0, heights=(1.5, 1.8), crouch_every=4.0,
                                crouch_depth=(0.25, 0.45), margin=0.2)


def _character_from():
    from repro.motion.runtime.fighter import character_from

    return character_from, dict(height=1.75, arm_scale=1.0, leg_scale=1.0, base=None)


def _check_target():
    from repro.motion.runtime.fighter import check_target

    return check_target, dict(target=[0.0, 1.6, 0.5])


# ------------------------------------------------------------------ the solver
def _adapt():
    from repro.motion.adaptation import AdaptOptions, adapt

    return adapt, dict(motion=_clip(), effector="right_fist", target=[0.0, 1.4, 0.6], t0=0, tc=5,
                       options=AdaptOptions(max_iter=10, hinge_range_deg=(0.0, 150.0)), roles=None, contacts=None,
                       root_offsets=None, frames=None, foot_offsets=None)


ADAPT_PARAMS = {
    "motion": "any", "effector": "choice", "target": "array", "t0": "int", "tc": "int", "options": "any",
    "roles": "mapping", "contacts": "array", "root_offsets": "array", "frames": "index_array", "foot_offsets": "array",
}


def _adapt_options():
    from repro.motion.adaptation import AdaptOptions

    return AdaptOptions, dict(kind="smoothstep", release=0.25, chain=None, limits=None, hinge_range_deg=(0.0, 150.0),
                              max_iter=10, tol=None, max_extension=0.98, feet="pin", foot_blend=0.1,
                              hit_point="joint", floor=None, max_foot_error=None)


ADAPT_OPTIONS_PARAMS = {
    "kind": "choice", "release": "real", "chain": "any", "limits": "mapping", "hinge_range_deg": "array",
    "max_iter": "int", "tol": "real", "max_extension": "real", "feet": "choice", "foot_blend": "real",
    "hit_point": "choice", "floor": "real", "max_foot_error": "real",
}


def _ccd():
    from repro.motion.adaptation import ccd

    return ccd, dict(motion=_clip(), frames=[1, 2], effector="right_fist", targets=[0.0, 1.4, 0.6], rotations=None,
                     chain=None, limits=None, max_iter=5, tol=None, finish_with_limb=True, max_extension=1.0,
                     hit_point="joint")


def _reach_limb():
    from repro.motion.adaptation import reach_limb

    return reach_limb, dict(motion=_clip(), frames=[1, 2], effector="right_fist", targets=[0.0, 1.4, 0.6],
                            rotations=None, hit_point="joint", tol=None, max_extension=1.0)


def _offset_curve():
    from repro.motion.adaptation import offset_curve

    return offset_curve, dict(t0=0, tc=3, d_tc=[0.0, 0.0, 0.1], frames=10, kind="linear", release=2)


def _default_chain():
    from repro.motion.adaptation import default_chain

    return default_chain, dict(motion=_clip(), effector="right_fist", include_pelvis=None)


def _adaptation_cost():
    from repro.motion.adaptation.cost import adaptation_cost

    return adaptation_cost, dict(reference=_clip(), adapted=_clip(), skeleton=None, frames=slice(1, None))


# ------------------------------------------------------------------ retargeting
def _retarget_across():
    from repro.motion.retargeting.trees import retarget_across

    return retarget_across, dict(motion=_clip(), character=_mixamo(), roles=None, character_roles=None,
                                 fix_feet=True, blend_time=0.1)


def _tree_plan():
    from repro.motion.retargeting.trees import TreePlan

    return TreePlan, dict(motion=_clip(), character=_mixamo(), roles=None, character_roles=None)


def _tree_positions():
    from repro.motion.retargeting.trees import TreePlan

    m = _clip()
    return TreePlan(m, _mixamo()).positions, dict(rotations=m.rotations, translations=m.local_translations(),
                                                  source=None)


def _body_frame():
    from repro.motion.retargeting.trees import body_frame

    return body_frame, dict(sk=_skeleton(), up="y")


def _retarget():
    from repro.motion.retargeting.morphology import retarget

    return retarget, dict(motion=_clip(), target=_character(), roles=None, fix_feet=True)


def _encode():
    from repro.motion.retargeting.morphology import encode

    return encode, dict(motion=_clip(), roles=None)


def _decode():
    from repro.motion.retargeting.morphology import decode, encode

    return decode, dict(mi=encode(_clip()), target=_character(), fix_feet=True, blend_time=0.1,
                        max_rest_angle_deg=5.0)


def _naive_retarget():
    from repro.motion.retargeting.morphology import naive_retarget

    return naive_retarget, dict(motion=_clip(), target=_character(), scale_root=True)


def _retarget_plan_positions():
    from repro.motion.retargeting.morphology import RetargetPlan

    m = _clip()
    return RetargetPlan(m, _character()).positions, dict(rotations=m.rotations, translations=m.local_translations(),
                                                         source=None)


# ------------------------------------------------------------------ skeletons, roles, motions
def _scale_skeleton():
    from repro.motion.body.skeleton import scale_skeleton

    return scale_skeleton, dict(skeleton=_skeleton(), height=1.8, scale=None, arm_scale=1.1, leg_scale=0.9,
                                trunk_scale=1.0, bone_scales=None)


def _skeleton_of():
    from repro.motion.body.skeleton import skeleton_of

    return skeleton_of, dict(x=_clip(), roles=None)


def _rescale_constraint():
    from repro.motion.body.skeleton import rescale_constraint

    return rescale_constraint, dict(c=[0.1, 1.2, 0.5], size_actor=1.7, size_character=1.8)


def _skeleton_method(attr, /, **kw):
    def setup():
        return getattr(_skeleton(), attr), kw

    return setup


def _with_offsets():
    sk = _skeleton()
    return sk.with_offsets, dict(offsets=sk.offsets * 2.0, end_site_offsets=None, unit_m=None)


def _find_roles():
    from repro.motion.body.roles import find_roles

    sk = _skeleton()
    return find_roles, dict(joint_names=list(sk.joint_names), parents=sk.parents, overrides=None,
                            offsets=sk.offsets, end_site_parents=sk.end_site_parents)


def _effector_role():
    from repro.motion.body.roles import effector_role

    sk = _skeleton()
    return effector_role, dict(roles=sk.roles, hit_role="right_fist", hit_joint=sk.roles["right_fist"])


def _check_roles():
    from repro.motion.body.roles import check_roles

    sk = _skeleton()
    return check_roles, dict(roles=sk.roles, purpose="a punch", joint_names=sk.joint_names)


def _motion_method(attr, /, **kw):
    def setup():
        return getattr(_clip(), attr), kw

    return setup


def _finite_vector3():
    from repro.motion.core.motion import finite_vector3

    return finite_vector3, dict(value=[0.0, 1.0, 2.0], name="target")


def _depth_levels():
    from repro.motion.core.kinematics import depth_levels

    return depth_levels, dict(parents=_skeleton().parents)


def _skeleton_ctor():
    from repro.motion.body.skeleton import Skeleton

    sk = _skeleton()
    return Skeleton, dict(joint_names=list(sk.joint_names), parents=sk.parents, offsets=sk.offsets,
                          channels=sk.channels, end_site_parents=sk.end_site_parents,
                          end_site_offsets=sk.end_site_offsets, unit_m=sk.unit_m, roles=dict(sk.roles))


def _motion_ctor():
    from repro.motion.core.motion import Motion

    m = _clip()
    return Motion, dict(joint_names=list(m.joint_names), parents=m.parents, offsets=m.offsets, channels=m.channels,
                        frame_time=m.frame_time, rotations=m.rotations, positions=m.positions,
                        end_site_parents=m.end_site_parents, end_site_offsets=m.end_site_offsets, unit_m=m.unit_m,
                        up=m.up)


def _infer_unit():
    from repro.motion.body.skeleton import infer_unit

    return infer_unit, dict(stature=1.75)


def _is_helper_name():
    from repro.motion.body.roles import is_helper_name

    return is_helper_name, dict(name="LeftHandIndex1")


def _rest_axes():
    from repro.motion.retargeting.trees import rest_axes

    return rest_axes, dict(sk=_skeleton())


def _cone_limits():
    from repro.motion.adaptation.ccd_solver import cone_limits

    return cone_limits, dict(motion=_clip(), limits={"spine": 20.0}, roles=None)


def _time_retarget():
    from repro.bench.retarget import time_retarget

    return time_retarget, dict(motion=_clip(), target=_character(), repeats=1)


def _motion_with():
    sk, m = _skeleton(), _clip()
    return sk.motion_with, dict(rotations=m.rotations[:3], positions=m.positions[:3], frame_time=1 / 30,
                                channels=None, up=None, source=None)


def _time_adaptation():
    from repro.bench.adaptation import time_adaptation

    return time_adaptation, dict(motion=_clip(), effector="right_fist", frames=[1, 2], offset=(0.0, 0.0, 0.05),
                                 repeats=1)


def _decode_with_report():
    from repro.motion.retargeting.morphology import decode_with_report, encode

    return decode_with_report, dict(mi=encode(_clip()), target=_character(), fix_feet=True, blend_time=0.1,
                                    max_rest_angle_deg=5.0)


@functools.cache
def _a_strike():
    return _strike()[0](**_strike()[1])


def _strike_summary():
    return _a_strike().summary, dict(timings=False)


CASES = [
    # the order pipeline
    Case("strike", _strike, STRIKE_PARAMS, time_limit=SLOW),
    Case("StrikeOptions", _strike_options, STRIKE_OPTIONS_PARAMS),
    Case("one_frame", _one_frame, {"motion": "any", "f": "int"}),
    Case("turn_and_move", _turn_and_move, {"motion": "any", "theta": "real", "translation": "array"}),
    Case("blend_into", _blend_into, {"pose": "any", "placed": "any", "n_blend": "int"}),
    Case("clip_effector", _clip_effector, {"db": "any", "clip": "int", "character": "any"}, time_limit=SLOW),
    Case("reach_by_distance", _reach_by_distance,
         {"distances": "array", "reached": "array", "levels": "array", "bins": "int"}),
    # the fighter
    Case("KungFuFighter", _fighter_ctor,
         {"character": "any", "height": "real", "arm_scale": "real", "leg_scale": "real", "seed": "int",
          "position": "array", "heading": "real", "options": "any", "across_trees": "bool"}, time_limit=SLOW),
    Case("KungFuFighter.place", _method("place", position=(0.3, -0.5), heading=0.2),
         {"position": "array", "heading": "real"}, time_limit=SLOW),
    Case("KungFuFighter.current_pose", _method("current_pose", frames=3), {"frames": "int"}, time_limit=SLOW),
    Case("KungFuFighter.advance", _method("advance", dt=0.1), {"dt": "real"}, time_limit=SLOW),
    Case("KungFuFighter.follow", _method("follow", head_position=(0.0, 1.6, 0.5), dt=0.05, snap=False),
         {"head_position": "array", "dt": "real", "snap": "bool"}, time_limit=SLOW),
    Case("KungFuFighter.order", _method("order", kind="punch", target=(0.0, 1.5, 0.2), commit=True),
         {"kind": "choice", "target": "array", "commit": "bool"}, time_limit=SLOW),
    Case("KungFuFighter.set_character", lambda: (_fighter().set_character, dict(character=_character())),
         {"character": "any"}, time_limit=SLOW),
    Case("simulated_user", _simulated_user,
         {"seed": "int", "duration": "real", "fps": "real", "heights": "array", "crouch_every": "real",
          "crouch_depth": "array", "margin": "real"}),
    Case("character_from", _character_from,
         {"height": "real", "arm_scale": "real", "leg_scale": "real", "base": "any"}),
    Case("check_target", _check_target, {"target": "array"}),
    # the solver
    # adapt and ccd compile the CCD kernel on their first call in a child with a cold numba cache (10.7 s
    # here, quiet; a case alone, REPRO_FUZZ_ARGS_CASE=ccd, has no strike before it to compile it)
    Case("adapt", _adapt, ADAPT_PARAMS, time_limit=SLOW),
    Case("AdaptOptions", _adapt_options, ADAPT_OPTIONS_PARAMS),
    Case("ccd", _ccd, {"motion": "any", "frames": "index_array", "effector": "choice", "targets": "array",
                       "rotations": "array", "chain": "any", "limits": "mapping", "max_iter": "int",
                       "tol": "real", "finish_with_limb": "bool", "max_extension": "real", "hit_point": "choice"},
         time_limit=SLOW),
    Case("reach_limb", _reach_limb, {"motion": "any", "frames": "index_array", "effector": "choice",
                                     "targets": "array", "rotations": "array", "hit_point": "choice",
                                     "tol": "real", "max_extension": "real"}),
    Case("offset_curve", _offset_curve, {"t0": "int", "tc": "int", "d_tc": "array", "frames": "int",
                                         "kind": "choice", "release": "int"}),
    Case("default_chain", _default_chain, {"motion": "any", "effector": "choice", "include_pelvis": "bool"}),
    Case("adaptation_cost", _adaptation_cost,
         {"reference": "any", "adapted": "any", "skeleton": "any", "frames": "any"}),
    # retargeting
    Case("retarget_across", _retarget_across,
         {"motion": "any", "character": "any", "roles": "mapping", "character_roles": "mapping",
          "fix_feet": "bool", "blend_time": "real"}),
    Case("TreePlan", _tree_plan, {"motion": "any", "character": "any", "roles": "mapping",
                                  "character_roles": "mapping"}),
    Case("TreePlan.positions", _tree_positions, {"rotations": "array", "translations": "array", "source": "any"}),
    Case("body_frame", _body_frame, {"sk": "any", "up": "choice"}),
    Case("retarget", _retarget, {"motion": "any", "target": "any", "roles": "mapping", "fix_feet": "bool"},
         time_limit=SLOW),
    Case("encode", _encode, {"motion": "any", "roles": "mapping"}),
    Case("decode", _decode, {"mi": "any", "target": "any", "fix_feet": "bool", "blend_time": "real",
                             "max_rest_angle_deg": "real"}, time_limit=SLOW),
    Case("naive_retarget", _naive_retarget, {"motion": "any", "target": "any", "scale_root": "bool"},
         time_limit=SLOW),
    Case("RetargetPlan.positions", _retarget_plan_positions,
         {"rotations": "array", "translations": "array", "source": "any"}, time_limit=SLOW),
    # skeletons, roles, motions, kinematics
    Case("scale_skeleton", _scale_skeleton,
         {"skeleton": "any", "height": "real", "scale": "real", "arm_scale": "real", "leg_scale": "real",
          "trunk_scale": "real", "bone_scales": "mapping"}),
    Case("skeleton_of", _skeleton_of, {"x": "any", "roles": "mapping"}),
    Case("rescale_constraint", _rescale_constraint, {"c": "array", "size_actor": "real", "size_character": "real"}),
    Case("Skeleton.index", _skeleton_method("index", name_or_role="left_knee"), {"name_or_role": "str"}),
    Case("Skeleton.path", _skeleton_method("path", ancestor="pelvis", descendant="right_wrist"),
         {"ancestor": "str", "descendant": "str"}),
    Case("Skeleton.rest_motion", _skeleton_method("rest_motion", n_frames=2, frame_time=1 / 30),
         {"n_frames": "int", "frame_time": "real"}),
    Case("Skeleton.to_metres", _skeleton_method("to_metres", value=2.0), {"value": "real"}),
    Case("Skeleton.with_offsets", _with_offsets,
         {"offsets": "array", "end_site_offsets": "array", "unit_m": "real"}),
    Case("find_roles", _find_roles, {"joint_names": "array", "parents": "index_array", "overrides": "mapping",
                                     "offsets": "array", "end_site_parents": "index_array"}),
    Case("effector_role", _effector_role, {"roles": "mapping", "hit_role": "str", "hit_joint": "str"}),
    Case("check_roles", _check_roles, {"roles": "mapping", "purpose": "choice", "joint_names": "array"}),
    Case("Motion.scaled", _motion_method("scaled", factor=2.0, unit_m=None), {"factor": "real", "unit_m": "real"}),
    Case("Motion.to_metres", _motion_method("to_metres", unit_m=0.01), {"unit_m": "real"}),
    Case("Motion.joint_index", _motion_method("joint_index", name="Hips"), {"name": "str"}),
    Case("finite_vector3", _finite_vector3, {"value": "array"}),
    Case("depth_levels", _depth_levels, {"parents": "index_array"}),
    Case("Skeleton", _skeleton_ctor,
         {"joint_names": "array", "parents": "index_array", "offsets": "array", "channels": "any",
          "end_site_parents": "index_array", "end_site_offsets": "array", "unit_m": "real", "roles": "mapping"}),
    Case("Motion", _motion_ctor,
         {"joint_names": "array", "parents": "index_array", "offsets": "array", "channels": "any",
          "frame_time": "real", "rotations": "array", "positions": "array", "end_site_parents": "index_array",
          "end_site_offsets": "array", "unit_m": "real", "up": "choice"}),
    Case("Skeleton.motion_with", _motion_with,
         {"rotations": "array", "positions": "array", "frame_time": "real", "channels": "any", "up": "choice",
          "source": "str"}),
    Case("infer_unit", _infer_unit, {"stature": "real"}),
    Case("is_helper_name", _is_helper_name, {"name": "str"}),
    Case("rest_axes", _rest_axes, {"sk": "any"}),
    Case("cone_limits", _cone_limits, {"motion": "any", "limits": "mapping", "roles": "mapping"}),
    Case("time_retarget", _time_retarget, {"motion": "any", "target": "any", "repeats": "int"}, time_limit=SLOW),
    Case("time_adaptation", _time_adaptation, {"motion": "any", "effector": "choice", "frames": "index_array",
                                               "offset": "array", "repeats": "int"}),
    Case("decode_with_report", _decode_with_report, {"mi": "any", "target": "any", "fix_feet": "bool",
                                                     "blend_time": "real", "max_rest_angle_deg": "real"},
         time_limit=SLOW),
    Case("Strike.summary", _strike_summary, {"timings": "bool"}, time_limit=SLOW),
]


def test_motion_runtime_arguments(tmp_path):
    check(__name__, log_dir=str(tmp_path))
