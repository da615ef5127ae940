"""Lewis, Mooser, Deng, Neumann, "Reducing Blendshape Interference by Selected
Motion Attenuation" (I3D 2005).

- :mod:`~repro.blendshapes.model`: the delta model ``f = f0 + D w`` and the
  whole-face form (Section 3).
- :mod:`~repro.blendshapes.procedural`: the embedded 2,016-vertex face.
- :mod:`~repro.blendshapes.ict`: the real ICT Face Model (staged data).
- :mod:`~repro.blendshapes.gltf`: glTF 2.0 faces (morph targets) in and out.
- :mod:`~repro.blendshapes.attenuation`: Eq. (3), ``attenuate`` and the cached
  ``Attenuator`` (Sections 4-5).
- :mod:`~repro.blendshapes.alternatives`: zeroed rows and orthogonal locking,
  the approaches Section 3 rejects.
- :mod:`~repro.blendshapes.metrics`: selected motion, unselected fidelity,
  surface smoothness.
"""

import os

from repro.blendshapes.alternatives import edit_orthogonal, edit_zeroed, orthogonal_lock, zero_rows
from repro.blendshapes.attenuation import (
    Attenuator,
    attenuate,
    check_selection,
    default_alpha,
    select_axis,
    select_pairs,
    select_vertices,
)
from repro.blendshapes.model import AXES, BlendshapeModel
from repro.errors import ModelError

__all__ = [
    "AXES",
    "BlendshapeModel",
    "MODELS",
    "load_model",
    "attenuate",
    "Attenuator",
    "default_alpha",
    "check_selection",
    "select_vertices",
    "select_pairs",
    "select_axis",
    "zero_rows",
    "edit_zeroed",
    "orthogonal_lock",
    "edit_orthogonal",
]

#: Models :func:`load_model` knows, with the dataset each needs (None = embedded).
MODELS = {"procedural": None, "ict": "ict"}  # and any .gltf/.glb path


def load_model(name="procedural", **kw) -> BlendshapeModel:
    """A blendshape model by name, or a glTF 2.0 face by path.

    A path (``str`` or ``os.PathLike``) ending in ``.gltf`` or ``.glb``: the face
    in that file, in metres (keywords of :func:`repro.blendshapes.gltf.read_gltf`).
    ``"procedural"``: the embedded 2,016-vertex face, always available
    (keyword ``n_vertices`` for a scaled-up one).  ``"ict"``: the ICT Face Model
    from the data folder (keywords of :func:`repro.blendshapes.ict.load_ict`);
    raises :class:`~repro.errors.DataError` saying how to get it when absent.
    A keyword the chosen loader does not take is a :class:`~repro.errors.ModelError`.
    """
    if isinstance(name, os.PathLike) or (isinstance(name, str) and name.lower().endswith((".gltf", ".glb"))):
        from repro.blendshapes.gltf import read_gltf

        unknown = sorted(set(kw) - {"mesh", "primitive", "max_bytes"})
        if unknown:
            raise ModelError(f"load_model of a glTF file takes only mesh=, primitive= and max_bytes=, got {unknown}")
        return read_gltf(name, **kw)
    if not isinstance(name, str):
        raise ModelError(f"model name must be a string or a .gltf/.glb path, got {name!r}; known: {sorted(MODELS)}")
    if name == "procedural":
        from repro.blendshapes.procedural import procedural_model

        unknown = sorted(set(kw) - {"n_vertices"})
        if unknown:
            raise ModelError(f"load_model('procedural') takes only n_vertices=, got {unknown}")
        return procedural_model(**kw)
    if name == "ict":
        from repro.blendshapes.ict import load_ict

        unknown = sorted(set(kw) - {"face_only", "shapes", "cache"})
        if unknown:
            raise ModelError(f"load_model('ict') takes only face_only=, shapes= and cache=, got {unknown}")
        return load_ict(**kw)
    raise ModelError(f"unknown model {name!r}; known: {sorted(MODELS)}")
