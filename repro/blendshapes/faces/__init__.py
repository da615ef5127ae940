"""Where faces come from: the delta models ``f = f0 + D w`` (Lewis et al. 2005, Section 3) the
attenuation runs on.

The paper's own face (Landreth's "Bingo", Figs. 2-5) is not available, so there are three sources:

- :mod:`~repro.blendshapes.faces.procedural`: the embedded 2,016-vertex face, built in code, with
  the paper's kinds of interference sculpted in (always available, no data).
- :mod:`~repro.blendshapes.faces.ict`: the real ICT Face Model (staged data), read through
  :mod:`~repro.blendshapes.faces.obj` (OBJ meshes that keep vertex identity).
- :mod:`~repro.blendshapes.faces.gltf`: any glTF 2.0 face with morph targets (the container in
  :mod:`~repro.blendshapes.faces.gltf_document`, which meshes make the face in
  :mod:`~repro.blendshapes.faces.gltf_meshes`, the paper's sliders and regions from ARKit-style
  shape names in :mod:`~repro.blendshapes.faces.arkit`, a VRM avatar's expressions as sliders in
  :mod:`~repro.blendshapes.faces.vrm`); :mod:`~repro.blendshapes.faces.gltf_write`
  writes a model, its weights and a weight animation back out.

:func:`load_model` picks one by name or path.
"""

import os

from repro.blendshapes.model import BlendshapeModel
from repro.errors import ModelError

__all__ = ["MODELS", "load_model"]

#: Models :func:`load_model` knows, with the dataset each needs (None = embedded).
MODELS = {"procedural": None, "ict": "ict"}  # and any .gltf/.glb/.vrm path


def load_model(name="procedural", **kw) -> BlendshapeModel:
    """A blendshape model by name, or a glTF 2.0 face by path.

    A path (``str`` or ``os.PathLike``) ending in ``.gltf``, ``.glb`` or ``.vrm``: the face
    in that file, in metres (keywords of :func:`repro.blendshapes.faces.gltf.read_gltf`; the
    face's meshes are found in a multi-mesh avatar, a VRM's expressions become sliders).
    ``"procedural"``: the embedded 2,016-vertex face, always available
    (keyword ``n_vertices`` for a scaled-up one).  ``"ict"``: the ICT Face Model
    from the data folder (keywords of :func:`repro.blendshapes.faces.ict.load_ict`);
    raises :class:`~repro.errors.DataError` saying how to get it when absent.
    A keyword the chosen loader does not take is a :class:`~repro.errors.ModelError`.
    """
    if isinstance(name, os.PathLike) or (isinstance(name, str) and name.lower().endswith((".gltf", ".glb", ".vrm"))):
        from repro.blendshapes.faces.gltf import read_gltf

        unknown = sorted(set(kw) - {"mesh", "primitive", "max_bytes"})
        if unknown:
            raise ModelError(f"load_model of a glTF file takes only mesh=, primitive= and max_bytes=, got {unknown}")
        return read_gltf(name, **kw)
    if not isinstance(name, str):
        raise ModelError(f"model name must be a string or a .gltf/.glb/.vrm path, got {name!r}; known: {sorted(MODELS)}")
    if name == "procedural":
        from repro.blendshapes.faces.procedural import procedural_model

        unknown = sorted(set(kw) - {"n_vertices"})
        if unknown:
            raise ModelError(f"load_model('procedural') takes only n_vertices=, got {unknown}")
        return procedural_model(**kw)
    if name == "ict":
        from repro.blendshapes.faces.ict import load_ict

        unknown = sorted(set(kw) - {"face_only", "shapes", "cache"})
        if unknown:
            raise ModelError(f"load_model('ict') takes only face_only=, shapes= and cache=, got {unknown}")
        return load_ict(**kw)
    raise ModelError(f"unknown model {name!r}; known: {sorted(MODELS)}")
