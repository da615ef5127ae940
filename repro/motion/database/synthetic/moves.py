"""The moves of the synthetic database: kinds, sides, target heights, semantics and hit points.

Pronost et al., Section 3.2.1: each clip of the database is annotated with "the name of the hit
segment (such as the right hand or the left foot) as well as the semantics (such as punching or
kicking)".  The synthetic set (:func:`~repro.motion.database.synthetic.synthetic_clip`) draws
its clips from this catalogue: every strike kind, on each side, at each target height.
"""

from __future__ import annotations

__all__ = [
    "HIT_LEVELS",
    "HIT_POINTS",
    "KINDS",
    "KIND_SEMANTICS",
    "SIDES",
    "STRIKE_KINDS",
    "TARGET_HEIGHT_FRACTION",
]

#: Motion kinds; the four strikes, then the idle fighting stance.
KINDS: tuple[str, ...] = ("punch", "kick_front", "kick_side", "kick_round", "stance")
#: The kinds that have a hit.
STRIKE_KINDS: tuple[str, ...] = KINDS[:4]
#: Striking side (the hand or foot that hits); for ``"stance"``, the side held back.
SIDES: tuple[str, ...] = ("left", "right")
#: Target heights of the hit; see :data:`TARGET_HEIGHT_FRACTION`.
HIT_LEVELS: tuple[str, ...] = ("high", "middle", "low")
#: Semantics of each kind, as annotated in the paper (Section 3.2.1).
KIND_SEMANTICS: dict[str, str] = {
    "punch": "punch",
    "kick_front": "kick",
    "kick_side": "kick",
    "kick_round": "kick",
    "stance": "other",
}

#: Hit point of each strike kind: ``(joint suffix, where)``; ``where`` is
#: ``"end_site"`` (the joint's End Site: the fist) or ``"joint"`` (the joint itself:
#: the ball of the foot for front kicks, the ankle for side kicks (heel) and round
#: kicks (instep)).  The joint name is ``"Left"`` or ``"Right"`` + suffix.
HIT_POINTS: dict[str, tuple[str, str]] = {
    "punch": ("Hand", "end_site"),
    "kick_front": ("ToeBase", "joint"),
    "kick_side": ("Foot", "joint"),
    "kick_round": ("Foot", "joint"),
}
#: Target height of the hit point, as a fraction of the actor height, per semantics and
#: level (face, chest, belly for punches; head, ribs, thigh for kicks).  Each clip adds
#: a uniform jitter of +-0.02 of the height.
TARGET_HEIGHT_FRACTION: dict[str, dict[str, float]] = {
    "punch": {"high": 0.90, "middle": 0.72, "low": 0.56},
    "kick": {"high": 0.86, "middle": 0.60, "low": 0.32},
}
