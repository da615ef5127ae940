"""repro: reproductions of two computer-animation papers as a tested library.

- :mod:`repro.blendshapes`: Lewis, Mooser, Deng, Neumann, "Reducing Blendshape
  Interference by Selected Motion Attenuation" (I3D 2005).
- ``repro.motion`` (to come): Pronost et al., "Interactive Animation of Virtual
  Characters: Application to Virtual Kung-fu Fighting" (about 2008).

Figures and measurements are registered in :mod:`repro.experiments` and run by
the ``repro`` command (``repro list``, ``repro run NAME``, ``repro all``).
"""

__version__ = "0.1.0"
