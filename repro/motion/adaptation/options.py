"""The options of the Section 3.4.2 edit (:func:`repro.motion.adaptation.adapt`), checked once.

Their defaults are the library's: the fighter's strike (:func:`repro.motion.runtime.strike.strike`)
plants the feet and keeps them above the floor at height 0 (``feet="plant"``, ``floor=0.0``) and eases ``d(t)``
with a smoothstep released over 0.25 s.  What depends on the skeleton (the chain's joint
names, the limits' keys, the default ``tol``) is checked by :func:`adapt` against its rig.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from repro.checks import as_bool, as_choice, as_int, as_names, as_real, as_real_array, as_str
from repro.errors import MotionError
from repro.motion.adaptation.ccd_solver import DEFAULT_HINGE_RANGE_DEG
from repro.motion.adaptation.offset import EASINGS
from repro.motion.adaptation.rig import check_extension
from repro.motion.core.motion import MAX_COORDINATE

__all__ = ["AdaptOptions", "FEET"]

#: how the other feet are held: pinned where planted around the edit, every contact phase
#: after ``t0`` planted, kept on their original trajectories, or left alone (None)
FEET = ("pin", "plant", "track", None)


@dataclass(frozen=True)
class AdaptOptions:
    """How :func:`~repro.motion.adaptation.adapt` edits a clip (Section 3.4.2).

    ``kind`` the easing of ``d(t)``; ``release`` seconds over which it is released after
    ``tc`` (None: held); ``chain`` / ``limits`` (degrees) / ``hinge_range_deg`` /
    ``max_iter`` are :func:`~repro.motion.adaptation.ccd`'s; ``tol`` the reach tolerance in
    motion units (None: 1e-4 of the limb length); ``max_extension`` the limb step's bound, a
    fraction of the limb length; ``feet`` one of :data:`FEET`; ``foot_blend`` seconds over
    which a foot pin is released; ``hit_point`` ``"joint"`` or ``"end_site"`` (the joint's tip: its End
    Site, else its fingers' knuckles, :func:`repro.motion.body.hit_points.hit_offset`); ``floor`` a
    height every foot (its joints and End Sites) stays above after ``t0``, the kicking foot too
    (None: no floor); ``max_foot_error`` a trial's bound
    on the support foot's error (None: unbounded); ``compiled`` CCD's sweeps by the compiled kernel
    (:mod:`repro.motion.adaptation.ccd_kernel`; False: by numpy, the same poses to rounding).  Raises :class:`repro.errors.MotionError`
    for a bad option.
    """

    kind: str = "smoothstep"
    release: float | None = 0.25
    chain: tuple[str, ...] | None = None
    limits: Mapping[str, float] | None = None
    hinge_range_deg: tuple[float, float] = DEFAULT_HINGE_RANGE_DEG
    max_iter: int = 50
    tol: float | None = None
    max_extension: float = 0.98
    feet: str | None = "plant"
    foot_blend: float = 0.1
    hit_point: str = "joint"
    floor: float | None = 0.0
    max_foot_error: float | None = None
    compiled: bool = True

    def __post_init__(self) -> None:
        def put(name, value):
            object.__setattr__(self, name, value)

        E = MotionError
        put("kind", as_choice(self.kind, "kind", EASINGS, error=E))
        if self.release is not None:
            put("release", as_real(self.release, "release (None or seconds)", error=E, lo=0.0))
        if self.chain is not None:
            put("chain", as_names(self.chain, "chain (joint names or roles)", error=E, nonempty=False))
        if self.limits is not None and not isinstance(self.limits, Mapping):
            raise E(f"limits must be a mapping of joint / role / kind -> degrees, got {type(self.limits).__name__}")
        h = as_real_array(self.hinge_range_deg, "hinge_range_deg (lo, hi) in degrees", error=E, shape=(2,))
        if not h[0] < h[1]:
            raise E(f"hinge_range_deg must be two finite numbers lo < hi, got {self.hinge_range_deg!r}")
        put("hinge_range_deg", (float(h[0]), float(h[1])))
        put("max_iter", as_int(self.max_iter, "max_iter", 0, 10**6, error=E))
        if self.tol is not None:
            put("tol", as_real(self.tol, "tol", error=E, lo=0.0, lo_open=True))
        put("max_extension", check_extension(self.max_extension))
        put("feet", as_choice(self.feet, "feet", FEET, error=E))
        put("foot_blend", as_real(self.foot_blend, "foot_blend (seconds)", error=E, lo=0.0))
        put("hit_point", as_str(self.hit_point, "hit_point ('joint' or 'end_site')", error=E))
        if self.floor is not None:
            put("floor", as_real(self.floor, "floor (a finite height or None)", error=E, lo=-MAX_COORDINATE,
                                 hi=MAX_COORDINATE))
        if self.max_foot_error is not None:
            put("max_foot_error", as_real(self.max_foot_error, "max_foot_error", error=E, lo=0.0))
        put("compiled", as_bool(self.compiled, "compiled", error=E))
