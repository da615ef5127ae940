"""Lewis, Mooser, Deng, Neumann, "Reducing Blendshape Interference by Selected
Motion Attenuation" (I3D 2005).

- :mod:`~repro.blendshapes.model`: the delta model ``f = f0 + D w`` (Section 3).
"""

from repro.blendshapes.model import AXES, BlendshapeModel

__all__ = ["AXES", "BlendshapeModel"]
