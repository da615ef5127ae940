"""The paper's sliders and selection regions on any face with ARKit-style shape names.

A glTF face from another tool carries no sliders or regions of the paper (Lewis et al. 2005,
Figs. 3-5), but most faces name their shapes after Apple's ARKit (``browDown_L`` or
``browDownLeft``), often behind a namespace and a group prefix (``face_shapes.ai_browDown_L``,
an FBX blend-shape node written by assimp) or with another side suffix (``_left``, ``.L``):
:func:`canonical_names` reads those conventions.  :func:`arkit_rig` maps the paper's sliders
onto the names, as :data:`~repro.blendshapes.faces.ict.ICT_SLIDERS` does for ICT, and finds the
figures' selections from where the named shapes move, not from vertex ids.  Shapes whose
names mean nothing in ARKit (visemes, FACS in-betweens such as ``eyeLowerClose_25_L``, a
``neutral`` target: :func:`neutral_targets`) stay shapes of their own, each set by its name.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence

import numpy as np

from repro.checks import as_real_array, describe
from repro.errors import ModelError

__all__ = ["arkit_rig", "canonical_names", "neutral_targets", "ARKIT_SLIDERS", "ARKIT_NAMES", "FACS_LIDS", "NEUTRAL_NAMES"]

#: The paper's sliders (Lewis et al. 2005, Figs. 3-5) over ARKit-style names, as for ICT
#: (:data:`repro.blendshapes.faces.ict.ICT_SLIDERS`); for each slider the first alternative whose
#: shapes are all in the face is used (ARKit's own ``browInnerUp`` is one shape, ICT splits it).
ARKIT_SLIDERS: dict[str, tuple[dict[str, float], ...]] = {
    "Furrow": ({"browDown_L": 1.0, "browDown_R": 1.0},),
    "SmirkLeft": ({"mouthSmile_L": 1.0},),
    "SmirkRight": ({"mouthSmile_R": 1.0},),
    "Wince": ({"eyeSquint_L": 1.0, "eyeSquint_R": 1.0},),
    "SneerLeft": ({"noseSneer_L": 1.0},),
    "SneerRight": ({"noseSneer_R": 1.0},),
    "JawOpen": ({"jawOpen": 1.0},),
    "MouthStretch": ({"mouthStretch_L": 1.0, "mouthStretch_R": 1.0},),
    "Smile": ({"mouthSmile_L": 1.0, "mouthSmile_R": 1.0},),
    "Blink": ({"eyeBlink_L": 1.0, "eyeBlink_R": 1.0},),
    "BrowUp": (
        {"browInnerUp_L": 1.0, "browInnerUp_R": 1.0, "browOuterUp_L": 1.0, "browOuterUp_R": 1.0},
        {"browInnerUp": 1.0, "browOuterUp_L": 1.0, "browOuterUp_R": 1.0},
    ),
}


#: FACS-style names of the lids, for the ARKit shapes they stand for on a face that has no ARKit name for them:
#: the upper lid closing (AU 43/45) is ``eyeBlink``, the lower lid raised (AU 7, the lid tightener) is
#: ``eyeSquint`` (the convention of FACS-named rigs such as Snap's Bitmoji faces: ``eyeUpperClose_L``,
#: ``eyeLowerClose_L``, beside in-betweens ``eyeUpperClose_50_L`` that stay shapes of their own).
FACS_LIDS = {"eyeBlink_L": "eyeUpperClose_L", "eyeBlink_R": "eyeUpperClose_R",
             "eyeSquint_L": "eyeLowerClose_L", "eyeSquint_R": "eyeLowerClose_R"}


#: Apple ARKit's 52 blendshape names (``ARFaceAnchor.BlendShapeLocation``), as Apple spells them.
ARKIT_NAMES = (
    "browDownLeft", "browDownRight", "browInnerUp", "browOuterUpLeft", "browOuterUpRight", "cheekPuff",
    "cheekSquintLeft", "cheekSquintRight", "eyeBlinkLeft", "eyeBlinkRight", "eyeLookDownLeft", "eyeLookDownRight",
    "eyeLookInLeft", "eyeLookInRight", "eyeLookOutLeft", "eyeLookOutRight", "eyeLookUpLeft", "eyeLookUpRight",
    "eyeSquintLeft", "eyeSquintRight", "eyeWideLeft", "eyeWideRight", "jawForward", "jawLeft", "jawOpen", "jawRight",
    "mouthClose", "mouthDimpleLeft", "mouthDimpleRight", "mouthFrownLeft", "mouthFrownRight", "mouthFunnel",
    "mouthLeft", "mouthLowerDownLeft", "mouthLowerDownRight", "mouthPressLeft", "mouthPressRight", "mouthPucker",
    "mouthRight", "mouthRollLower", "mouthRollUpper", "mouthShrugLower", "mouthShrugUpper", "mouthSmileLeft",
    "mouthSmileRight", "mouthStretchLeft", "mouthStretchRight", "mouthUpperUpLeft", "mouthUpperUpRight",
    "noseSneerLeft", "noseSneerRight", "tongueOut",
)  # fmt: skip
#: Side suffixes written by other tools, as ARKit's ``_L`` / ``_R`` (``Left`` / ``Right`` after a
#: lower-case letter is handled separately, so that ``mouthLeft`` keeps its meaning as a whole).
_SIDE_SUFFIXES = (("_Left", "_L"), ("_Right", "_R"), ("_left", "_L"), ("_right", "_R"), ("_l", "_L"), ("_r", "_R"),
                  (".L", "_L"), (".R", "_R"), (".l", "_L"), (".r", "_R"))
#: Namespace separators: ``face_shapes.ai_browDown_L`` (FBX blend-shape channel through assimp),
#: ``head:jawOpen`` (Maya), ``rig|jawOpen`` (a DAG path).
_NAMESPACE_SEPARATORS = (".", ":", "|")
#: A group prefix (``ai_``, ``ca_``): one to four lower-case letters and ``_`` before a camelCase name.
_GROUP_PREFIX = re.compile(r"^([a-z]{1,4})_(?=[a-z])")
#: Names of a target that is the neutral pose itself (not an expression), after the namespace and group prefix.
NEUTRAL_NAMES = ("neutral", "basis", "base", "default", "rest")


def _side(name: str) -> str:
    """``browDownLeft``, ``browDown_left``, ``browDown.L`` ... as ``browDown_L``; other names unchanged."""
    for long, short in _SIDE_SUFFIXES:
        if name.endswith(long) and len(name) > len(long):
            return name[: -len(long)] + short
    for long, short in (("Left", "_L"), ("Right", "_R")):
        if name.endswith(long) and len(name) > len(long) and name[-len(long) - 1].isalpha() and name[0].isalpha():
            return name[: -len(long)] + short
    return name


_ARKIT_CANON = {_side(n).lower(): _side(n) for n in ARKIT_NAMES}


def canonical_names(names: Sequence[str]) -> list[str]:
    """Each shape name in the form the sliders and regions are looked up by (ARKit's ``browDown_L``).

    The convention of many exporters, not of one file: a namespace is dropped (``face_shapes.`` in
    ``face_shapes.ai_browDown_L``, ``head:`` in ``head:jawOpen``); a group prefix of one to four
    lower-case letters (``ai_``, ``ca_``) is dropped when at least two names carry it; a side suffix
    (``Left``, ``_left``, ``_l``, ``.L`` ...) becomes ``_L`` / ``_R``; and a name that is one of
    :data:`ARKIT_NAMES` whatever its case (``JawOpen``) is spelled as ARKit spells it.  In-between
    shapes (``eyeLowerClose_25_L``, ``_50_``, ``_75_``: the shape part of the way) keep their
    number, so they never stand for the full shape; like every name that means nothing in
    ARKit they stay shapes of their own (a slider under the file's name), in no named slider.
    """
    bare = []
    for name in names:
        s = _side(name)  # before the namespace: ``browDown.L`` is a side, not a namespace
        for sep in _NAMESPACE_SEPARATORS:
            s = s.rsplit(sep, 1)[-1] if not s.endswith(sep) else s
        bare.append(s if s else name)
    prefixes = [m.group(1) if (m := _GROUP_PREFIX.match(s)) else None for s in bare]
    shared = {p for p in prefixes if p is not None and prefixes.count(p) >= 2}
    out = []
    for s, p in zip(bare, prefixes):
        if p in shared:
            s = s[len(p) + 1 :]
        out.append(_ARKIT_CANON.get(s.lower(), s))
    return out


def neutral_targets(names: Sequence[str]) -> list[int]:
    """Shapes named as the neutral pose itself (``neutral``, ``face_shapes.ai_neutral``, ``Basis`` ...)."""
    return [k for k, s in enumerate(canonical_names(names)) if s.lower() in NEUTRAL_NAMES]


def arkit_rig(f0, D, names: Sequence[str], aliases: Mapping[str, Mapping[str, float]] | None = None) -> tuple[dict, dict]:
    """The paper's sliders and selection regions of a face with ARKit-style shape names.

    Sliders: :data:`ARKIT_SLIDERS` (the ICT mapping), over the face's own names
    (``browDown_L``, ``browDownLeft``, ``face_shapes.ai_browDown_L``: :func:`canonical_names`),
    those whose shapes are all present.  ``aliases`` stand for ARKit shapes the face has under
    no name, as combinations of its shapes (a VRM face's ``blink_l`` expression for ``eyeBlink_L``,
    :func:`~repro.blendshapes.faces.vrm.vrm_expressions`); a shape of the face itself comes first,
    then an alias, then a FACS-named lid (:data:`FACS_LIDS`: ``eyeUpperClose_L`` for ``eyeBlink_L``).
    Regions, found from where the named shapes move (not from vertex ids), with
    ``|d_k(v)|`` the motion of vertex ``v`` under shape ``k`` at weight 1 and the
    subject's left-right axis running from the motion centroid of the ``_R``
    shape to that of the ``_L`` shape:

    - ``left_eye`` / ``right_eye``: vertices ``eyeBlink_L/R`` moves at least 25% of its peak;
    - ``brow``: vertices ``browDown_L + browDown_R`` moves at least 25% of its peak;
      ``brow_middle`` (Fig. 3): on each side of the midline the vertex nearest to it among
      those that side's ``browDown`` moves at least half its peak (right side first);
    - ``mouth_corners`` (Fig. 4): the vertex ``mouthSmile_R`` moves most, then ``mouthSmile_L``'s;
    - ``under_left_eye`` (Fig. 5): the six vertices where both ``eyeSquint_L`` and
      ``noseSneer_L`` move most (largest ``min`` of the two motions), outside ``left_eye``;
    - ``mouth``, ``nose``: at least 25% of the peak of ``mouthSmile_L + _R`` / ``noseSneer_L + _R``.

    Regions whose shapes the face lacks are left out (scenarios needing them say so).
    """
    f0, D = _check_face(f0, D, names)
    by_canon: dict[str, dict[int, float]] = {}
    for k, s in enumerate(canonical_names(names)):
        by_canon.setdefault(s, {k: 1.0})
    index = {s: k for k, s in enumerate(names)}
    for s, combo in (aliases or {}).items():
        by_canon.setdefault(s, {index[t]: float(c) for t, c in combo.items()})
    for s, facs in FACS_LIDS.items():  # a FACS-named lid stands for the ARKit shape the face lacks
        if s not in by_canon and facs in by_canon:
            by_canon[s] = by_canon[facs]

    def motion(*shapes):
        """``|sum of the shapes' deltas|`` per vertex, or None when the face lacks one of them."""
        if not all(s in by_canon for s in shapes):
            return None
        combos = [by_canon[s] for s in shapes]
        if all(list(c.values()) == [1.0] for c in combos):  # plain shapes
            return np.linalg.norm(D[:, :, [next(iter(c)) for c in combos]].sum(axis=2), axis=1)
        w = np.zeros(D.shape[2])
        for c in combos:
            for k, coef in c.items():
                w[k] += coef
        return np.linalg.norm(D @ w, axis=1)

    regions = _bands(motion)
    if (pick := _brow_middle(f0, motion("browDown_L"), motion("browDown_R"))) is not None:
        regions["brow_middle"] = pick
    sR, sL = motion("mouthSmile_R"), motion("mouthSmile_L")
    if sR is not None and sL is not None and sR.max() > 0 and sL.max() > 0:
        regions["mouth_corners"] = np.array([int(np.argmax(sR)), int(np.argmax(sL))])
    if (under := _under_left_eye(motion("eyeSquint_L"), motion("noseSneer_L"), regions.get("left_eye"))) is not None:
        regions["under_left_eye"] = under
    return _sliders(names, by_canon), regions


def _check_face(f0, D, names) -> tuple[np.ndarray, np.ndarray]:
    """``f0`` as (n, 3) and ``D`` as (n, 3, m), with one name per shape, or a :class:`ModelError`."""
    f0 = as_real_array(f0, "f0", shape=(None, 3), error=ModelError)
    n = len(f0)
    D = as_real_array(D, "D", error=ModelError)
    if not ((D.ndim == 2 and D.shape[0] == 3 * n) or (D.ndim == 3 and D.shape[:2] == (n, 3))):
        raise ModelError(f"D must have shape (3n, m) or (n, 3, m) for the n = {n} vertices of f0, got {D.shape}")
    D = D.reshape(n, 3, -1)
    if isinstance(names, (str, bytes)) or not isinstance(names, Sequence) or len(names) != D.shape[2] \
            or not all(isinstance(s, str) for s in names):
        raise ModelError(f"names must be {D.shape[2]} strings, one per shape, got {describe(names)}")
    return f0, D


def _sliders(names: Sequence[str], by_canon: dict[str, dict[int, float]]) -> dict[str, dict[str, float]]:
    """:data:`ARKIT_SLIDERS` over the face's own names: the first alternative whose shapes are all there."""
    sliders: dict[str, dict[str, float]] = {}
    for slider, options in ARKIT_SLIDERS.items():
        if slider in names:
            continue
        for combo in options:
            if all(s in by_canon for s in combo):
                out: dict[str, float] = {}
                for s, c in combo.items():
                    for k, coef in by_canon[s].items():
                        out[names[k]] = out.get(names[k], 0.0) + c * coef
                sliders[slider] = out
                break
    return sliders


def _bands(motion) -> dict[str, np.ndarray]:
    """``left_eye``, ``right_eye``, ``brow``, ``mouth``, ``nose``: at least 25% of their shapes' peak motion."""
    def band(mv, frac=0.25):
        if mv is None or mv.max() <= 0:
            return None
        return np.flatnonzero(mv >= frac * mv.max())

    regions: dict[str, np.ndarray] = {}
    for key, shapes in (("left_eye", ("eyeBlink_L",)), ("right_eye", ("eyeBlink_R",)), ("brow", ("browDown_L", "browDown_R")),
                        ("mouth", ("mouthSmile_L", "mouthSmile_R")), ("nose", ("noseSneer_L", "noseSneer_R"))):
        if (b := band(motion(*shapes))) is not None:
            regions[key] = b
    return regions


def _brow_middle(f0: np.ndarray, mL, mR) -> np.ndarray | None:
    """Fig. 3: each side's vertex nearest the midline among those its ``browDown`` moves at least half its peak."""
    if mL is None or mR is None or not (mL.max() > 0 and mR.max() > 0):
        return None
    cL, cR = (mL @ f0) / mL.sum(), (mR @ f0) / mR.sum()
    axis = cL - cR
    if not np.linalg.norm(axis) > 0:
        return None
    axis /= np.linalg.norm(axis)
    side = (f0 - 0.5 * (cL + cR)) @ axis  # > 0 on the subject's left
    pick = []
    for mv, sgn in ((mR, -1.0), (mL, 1.0)):
        cand = np.flatnonzero((mv >= 0.5 * mv.max()) & (sgn * side > 0))
        if cand.size:
            pick.append(int(cand[np.lexsort((cand, np.abs(side[cand])))][0]))
    return np.array(pick) if len(pick) == 2 else None


def _under_left_eye(sq, sn, left_eye) -> np.ndarray | None:
    """Fig. 5: the six vertices where both ``eyeSquint_L`` and ``noseSneer_L`` move most, outside ``left_eye``."""
    if sq is None or sn is None:
        return None
    both = np.minimum(sq, sn)
    if left_eye is not None:
        both[left_eye] = -1.0
    ids = np.arange(len(both))
    order = np.lexsort((ids, -both))[:6]
    return np.sort(order) if both[order].min() > 0 else None
