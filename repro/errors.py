"""Exceptions raised by :mod:`repro`.

Every error a user can provoke with bad input (a malformed file, a mismatched
mesh, a NaN weight, an empty selection, ``alpha <= 0`` ...) is raised as one of
these classes, with a message that names the bad value and what was expected.
All of them derive from :class:`ReproError`, so ``except ReproError`` catches
everything the library raises on purpose.  Those about bad *values* also derive
from :class:`ValueError`, so code written against plain Python conventions keeps
working.
"""

from __future__ import annotations

__all__ = [
    "ReproError",
    "ArgumentError",
    "DataError",
    "ModelError",
    "SelectionError",
    "AttenuationError",
    "BVHError",
    "MotionError",
    "RetrievalError",
    "UnknownFigureError",
    "RenderUnavailableError",
    "ReproWarning",
    "BVHWarning",
    "UnitWarning",
    "CacheWarning",
]


class ReproError(Exception):
    """Base class of every error raised on purpose by :mod:`repro`."""


class ArgumentError(ReproError, ValueError):
    """An argument of the wrong type, shape or range (the message names it and what was expected).

    The packages raise their own subclass-free errors (``ModelError``, ``MotionError`` ...) for
    their arguments; this is the default of :mod:`repro.checks` and the error of the shared ground.
    """


class DataError(ReproError):
    """A dataset is missing, fails its sha256 check, or could not be fetched."""


class ModelError(ReproError, ValueError):
    """A blendshape model is inconsistent (shapes of arrays, NaN, bad faces, unknown names)."""


class SelectionError(ReproError, ValueError):
    """A coordinate selection is empty, duplicated, out of range or otherwise unusable."""


class AttenuationError(ReproError, ValueError):
    """Motion attenuation (Lewis et al. 2005, Eq. 3) cannot be solved for these inputs."""


class BVHError(ReproError, ValueError):
    """A BVH (or ASF/AMC) file is malformed; the message names the line or field."""


class MotionError(ReproError, ValueError):
    """A motion, skeleton or character is unusable (missing role, zero-length bone, NaN target ...)."""


class RetrievalError(ReproError, ValueError):
    """A motion-database query cannot be answered (empty database, unknown semantics ...)."""


class UnknownFigureError(ReproError, KeyError):
    """No figure or measurement is registered under this name."""

    def __str__(self) -> str:  # KeyError would otherwise repr() the message
        return str(self.args[0]) if self.args else ""


class RenderUnavailableError(ReproError, RuntimeError):
    """Off-screen 3D rendering (VTK/pyvista) is not available on this machine."""


class ReproWarning(UserWarning):
    """Base class of every warning issued on purpose by :mod:`repro`."""


class BVHWarning(ReproWarning):
    """A BVH (or ASF/AMC) file was read, but part of it was ignored (e.g. text after the frames)."""


class UnitWarning(ReproWarning):
    """A length unit or up axis was not given and was inferred (the message says which)."""


class CacheWarning(ReproWarning):
    """A derived cache did not match its sources or its content hash and was rebuilt."""
