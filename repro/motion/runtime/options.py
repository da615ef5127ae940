"""How an order is carried out (:func:`repro.motion.runtime.strike.strike`), checked once.

:class:`StrikeOptions` holds every choice of the runtime sequence of Pronost et al.
(Sections 3.3-3.4): the search, the blend, the retargeting's foot pass, how far the
whole-body reach may go, and the frame-by-frame edit (:class:`~repro.motion.adaptation.AdaptOptions`).
Its defaults are the library's, the fighter's and the panels' alike: the exact optimum of
Eq. 1's ``d`` (``method="exact"``: the same clip the exhaustive scan finds, faster than the
paper's pruning on every database measured, ``repro bench retrieval``).  The figures that
reproduce the paper pass the paper's choices, :data:`repro.motion.runtime.paper.PAPER`
(its pruned search, Section 3.3), explicitly.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from repro.checks import as_bool, as_choice, as_real, describe
from repro.errors import MotionError, RetrievalError
from repro.motion.adaptation import AdaptOptions
from repro.motion.search.arguments import METHODS

__all__ = ["BLEND_S", "MAX_ROOT_SHIFT", "REACH_LEVELS", "StrikeOptions"]

#: Seconds over which a selected clip is blended into the current pose.
BLEND_S: float = 0.2
#: Levels of whole-body reach, in order: two-bone limb IK, + CCD over the spine / pelvis, + a root shift,
#: + a step of the front foot (punches).
REACH_LEVELS: tuple[str, ...] = ("limb", "spine", "root", "step")
#: Largest root shift of the ``"root"`` level, per metre of the character's leg length.
MAX_ROOT_SHIFT: float = 0.35


@dataclass(frozen=True)
class StrikeOptions:
    """How :func:`~repro.motion.runtime.strike.strike` carries out an order (Sections 3.3-3.4).

    Attributes
    ----------
    method : str, default "exact"
        The search (:meth:`~repro.motion.search.retrieval.MotionRetriever.search`): ``"exact"``
        (the exhaustive optimum of ``d``, by bounds), ``"pruned"`` (the paper's cluster and
        box pruning, Section 3.3), ``"kdtree"`` or ``"exhaustive"``.
    blend_s : float, default :data:`BLEND_S`
        Seconds of the blend with the current pose (at most up to the contact).
    fix_feet : bool, default False
        ``retarget(..., fix_feet=...)``: the decoder's own foot pass (Section 3.4.1).
    reach : {"limb", "spine", "root", "step"}, default "root"
        Highest level of whole-body reach allowed (:data:`REACH_LEVELS`; ``"step"``: punches
        only, a kick's foot lifts within frames of the order, so its support foot never steps).
    max_root_shift : float, default :data:`MAX_ROOT_SHIFT`
        Cap of the root shift, per metre of leg length.
    adapt : AdaptOptions
        The frame-by-frame edit (Section 3.4.2): the feet, the floor, the easing of ``d(t)``
        and its release, the limits.  Its ``hit_point``, ``max_iter`` and ``max_foot_error``
        are set by the strike for each clip and reach level.
    early_stop : bool, default True
        A root-shift trial whose support foot fails is stopped before its hit solve when
        the feet do not depend on it (a punch).  False solves every trial in full: the slow
        path, with the same results.
    stream : bool, default True
        Decide the level on the contact frame and frame ``t0 + 1`` before solving the rest
        of the clip (a kick planted at ``t0 + 1``: that frame first, then the level); False
        solves every level on the whole clip first (the same strike; ``first_frame`` is then
        the whole adaptation).

    Raises :class:`repro.errors.MotionError` for a bad option (a bad ``method``:
    :class:`repro.errors.RetrievalError`, the search's).
    """

    method: str = "exact"
    blend_s: float = BLEND_S
    fix_feet: bool = False
    reach: str = "root"
    max_root_shift: float = MAX_ROOT_SHIFT
    adapt: AdaptOptions = field(default_factory=AdaptOptions)
    early_stop: bool = True
    stream: bool = True

    def __post_init__(self) -> None:
        def put(name, value):
            object.__setattr__(self, name, value)

        put("method", as_choice(self.method, "method", METHODS, error=RetrievalError))
        put("blend_s", as_real(self.blend_s, "blend_s (seconds)", error=MotionError, lo=0.0))
        put("fix_feet", as_bool(self.fix_feet, "fix_feet", error=MotionError))
        put("reach", as_choice(self.reach, "reach", REACH_LEVELS, error=MotionError))
        put("max_root_shift", as_real(self.max_root_shift, "max_root_shift (per metre of leg length)",
                                      error=MotionError, lo=0.0))
        if not isinstance(self.adapt, AdaptOptions):
            raise MotionError(f"adapt must be an AdaptOptions, got {describe(self.adapt)}")
        put("early_stop", as_bool(self.early_stop, "early_stop", error=MotionError))
        put("stream", as_bool(self.stream, "stream", error=MotionError))
