"""The paper's sliders and selection regions on any face with ARKit-style shape names.

A glTF face from another tool carries no sliders or regions of the paper (Lewis et al. 2005,
Figs. 3-5), but most faces name their shapes after Apple's ARKit (``browDown_L`` or
``browDownLeft``).  :func:`arkit_rig` maps the paper's sliders onto those names, as
:data:`~repro.blendshapes.faces.ict.ICT_SLIDERS` does for ICT, and finds the figures'
selections from where the named shapes move, not from vertex ids.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from repro.checks import as_real_array, describe
from repro.errors import ModelError

__all__ = ["arkit_rig", "ARKIT_SLIDERS"]

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


def _canonical(name: str) -> str:
    """ARKit camelCase (``browDownLeft``) as ARKit's own ``browDown_L``; other names unchanged."""
    for long, short in (("Left", "_L"), ("Right", "_R")):
        if name.endswith(long) and len(name) > len(long) and name[0].islower():
            return name[: -len(long)] + short
    return name


def arkit_rig(f0, D, names: Sequence[str]) -> tuple[dict, dict]:
    """The paper's sliders and selection regions of a face with ARKit-style shape names.

    Sliders: :data:`ARKIT_SLIDERS` (the ICT mapping), over the face's own names
    (``browDown_L`` or ``browDownLeft``), those whose shapes are all present.
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
    by_canon: dict[str, int] = {}
    for k, s in enumerate(names):
        by_canon.setdefault(_canonical(s), k)

    def motion(*shapes):
        """``|sum of the shapes' deltas|`` per vertex, or None when the face lacks one of them."""
        if not all(s in by_canon for s in shapes):
            return None
        return np.linalg.norm(D[:, :, [by_canon[s] for s in shapes]].sum(axis=2), axis=1)

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


def _sliders(names: Sequence[str], by_canon: dict[str, int]) -> dict[str, dict[str, float]]:
    """:data:`ARKIT_SLIDERS` over the face's own names: the first alternative whose shapes are all there."""
    sliders: dict[str, dict[str, float]] = {}
    for slider, options in ARKIT_SLIDERS.items():
        if slider in names:
            continue
        for combo in options:
            if all(s in by_canon for s in combo):
                sliders[slider] = {names[by_canon[s]]: c for s, c in combo.items()}
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
