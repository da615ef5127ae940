"""One way to put a clip on a character (Section 3.4.1), whatever its joint tree.

A character of the database actor's joint tree is retargeted through Kulpa et al.'s
morphology-independent representation (:mod:`repro.motion.retargeting.morphology`); a
character of another tree through the body-part roles
(:mod:`repro.motion.retargeting.trees`).  :func:`retarget_to` chooses; the retrieval, the
strike and the fighter all go through it.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from repro.checks import as_str, describe
from repro.errors import MotionError
from repro.motion.body.roles import check_roles, find_roles
from repro.motion.body.skeleton import Skeleton, skeleton_of
from repro.motion.core.motion import Motion
from repro.motion.retargeting.morphology import retarget
from repro.motion.retargeting.trees import retarget_across

__all__ = ["character_skeleton", "rest_motion_y_up", "retarget_to_tree", "retarget_to"]


_ROT_CH = ("Zrotation", "Xrotation", "Yrotation")
_POS_CH = ("Xposition", "Yposition", "Zposition")


def character_skeleton(character, purposes: Sequence[str] = ()) -> Skeleton:
    """The Skeleton of a character (Skeleton or Motion) that must be able to do ``purposes``.

    ``purposes``: keys of :data:`repro.motion.body.roles.ROLES_FOR` (``"a punch"``, ``"a kick"``).
    A partial skeleton (legs only, arms only) is refused naming what is missing *for
    what* (:func:`repro.motion.body.roles.check_roles`: "a punch needs an arm ...") rather
    than only the roles a Skeleton needs.

    Raises
    ------
    repro.errors.MotionError
    """
    if isinstance(purposes, str):
        purposes = (purposes,)
    try:
        purposes = tuple(as_str(p, "purposes entry", error=MotionError) for p in purposes)
    except TypeError:
        raise MotionError(f"purposes must be a sequence of purposes such as 'a punch', got {describe(purposes)}") from None
    try:
        ch = skeleton_of(character)
    except MotionError as e:
        names, par, off = (getattr(character, k, None) for k in ("joint_names", "parents", "offsets"))
        if names is not None and par is not None and off is not None:
            try:
                partial = find_roles(list(names), np.asarray(par), offsets=np.asarray(off, dtype=float), required=())
            except MotionError:
                raise e from None
            _check_purposes(partial, purposes, list(names))
        raise
    _check_purposes(ch.roles, purposes, ch.joint_names)
    return ch


def _check_purposes(roles, purposes, names) -> None:
    """:func:`check_roles` of every purpose; one MotionError naming every purpose that fails."""
    why = []
    for purpose in purposes:
        try:
            check_roles(roles, purpose, names)
        except MotionError as e:
            why.append(str(e).split("; joints:")[0])
    if why:
        raise MotionError("; ".join(why) + f"; joints: {list(names)}")


def rest_motion_y_up(character) -> Motion:
    """The rest pose of ``character`` (Skeleton or Motion) as a one-frame Motion in the database
    world (Y up): the target :func:`retarget_to_tree` decodes onto.  A database actor's rest
    pose need not stand along Y (Bandai's lies along +X), but its clips do."""
    sk = skeleton_of(character)
    J = sk.n_joints
    rot = np.zeros((1, J, 4))
    rot[..., 3] = 1.0
    channels = list(sk.channels) if sk.channels is not None else [_POS_CH + _ROT_CH] + [_ROT_CH] * (J - 1)
    return Motion.from_unit_rotations(
        joint_names=list(sk.joint_names), parents=sk.parents, offsets=sk.offsets, channels=channels,
        frame_time=1.0 / 30.0, rotations=rot, positions=np.asarray(sk.offsets, dtype=float)[None].copy(),
        end_site_parents=sk.end_site_parents, end_site_offsets=sk.end_site_offsets, unit_m=sk.unit_m, up="y")


def retarget_to_tree(motion: Motion, character, *, roles=None, target=None, fix_feet: bool = False) -> Motion:
    """``motion`` (database world: Y up, metres) played by ``character`` of another joint tree.

    Through the body-part roles (:func:`repro.motion.retargeting.trees.retarget_across`), the
    character's own role table (``character.roles``; an explicit one is kept) and its
    rest pose decoded in the Y-up world (:func:`rest_motion_y_up`, or ``target`` when
    already made).  ``roles``: the motion's role table (default: found); ``fix_feet``: see
    :func:`~repro.motion.retargeting.trees.retarget_across`.  The result is a Motion on the
    character's skeleton, Y up.

    Raises
    ------
    repro.errors.MotionError
        Missing roles on either side (named), a rest pose whose facing cannot be told.
    """
    if not isinstance(motion, Motion):
        raise MotionError(f"motion must be a repro.motion.Motion, got {describe(motion)}")
    if target is not None and not isinstance(target, Motion):
        raise MotionError(f"target must be a repro.motion.Motion (a rest pose) or None, got {describe(target)}")
    ch = skeleton_of(character)
    src = motion if motion.up is not None else dataclasses.replace(motion, up="y")
    tgt = rest_motion_y_up(ch) if target is None else target
    return retarget_across(src, tgt, roles=roles, character_roles=dict(ch.roles), fix_feet=fix_feet)


def retarget_to(motion: Motion, character, *, fix_feet: bool = False) -> Motion:
    """``motion`` played by ``character`` (a Skeleton or Motion): :func:`~repro.motion.retargeting.morphology.retarget`
    when the character has the motion's joint tree, :func:`retarget_to_tree` otherwise."""
    ch = skeleton_of(character)
    if ch.is_compatible(motion):
        return retarget(motion, ch, fix_feet=fix_feet)
    return retarget_to_tree(motion, ch, fix_feet=fix_feet)
