"""Lewis, Mooser, Deng, Neumann, "Reducing Blendshape Interference by Selected
Motion Attenuation" (I3D 2005), as a map of the paper's pieces.

The model and where it comes from:

- :mod:`~repro.blendshapes.model` (Section 3): the delta model ``f = f0 + D w``
  and the whole-face form.
- :mod:`~repro.blendshapes.faces`: the faces to run it on, apart from the model
  because they are data, not method: the embedded procedural face, the ICT Face
  Model (OBJ), any glTF 2.0 face read and written (:func:`load_model`,
  :func:`read_gltf`, :func:`write_gltf`).

The method and what the paper compares it with, each a function of a model:

- :mod:`~repro.blendshapes.attenuation` (Sections 4-5): Eq. (3), ``attenuate``
  and the cached ``Attenuator``, the selections, the default ``alpha``.
- :mod:`~repro.blendshapes.alternatives` (Section 3): zeroed rows and orthogonal
  locking, the approaches the paper rejects.
- :mod:`~repro.blendshapes.metrics`: selected motion, unselected fidelity,
  surface smoothness: the numbers the figures report.
- :mod:`~repro.blendshapes.scenarios` (Figs. 1-5): the paper's slider sessions.
- :mod:`~repro.blendshapes.bounded` and :mod:`~repro.blendshapes.manipulation`:
  beyond the paper, Eq. (2) with sliders kept in range, and direct manipulation
  (Lewis and Anjyo 2010) on the same Gram machinery.

The names below are what figures, panels and notebooks use; everything else is
imported from its module.
"""

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
from repro.blendshapes.faces import MODELS, load_model
from repro.blendshapes.faces.gltf import read_gltf
from repro.blendshapes.faces.gltf_write import write_gltf
from repro.blendshapes.model import AXES, BlendshapeModel

__all__ = [
    # Section 3: the model, and the faces
    "BlendshapeModel", "AXES", "MODELS", "load_model", "read_gltf", "write_gltf",
    # Sections 4-5: Eq. (3) and its selections
    "attenuate", "Attenuator", "default_alpha", "check_selection", "select_vertices", "select_pairs", "select_axis",
    # Section 3's rejected approaches
    "zero_rows", "edit_zeroed", "orthogonal_lock", "edit_orthogonal",
]  # fmt: skip
