"""repro: reproductions of two computer-animation papers as a tested library.

The two papers, each a library package whose docstring maps it:

- :mod:`repro.blendshapes`: Lewis, Mooser, Deng, Neumann, "Reducing Blendshape
  Interference by Selected Motion Attenuation" (I3D 2005): the model, its faces, Eq. 3
  and the alternatives it rejects.
- :mod:`repro.motion`: Pronost et al., "Interactive Animation of Virtual Characters:
  Application to Virtual Kung-fu Fighting" (about 2008): its pipeline as subpackages,
  ``core``, ``io``, ``body``, ``retargeting``, ``database``, ``search``, ``adaptation``,
  ``runtime``.

The ground both stand on: :mod:`repro.errors` (what the library raises on purpose),
:mod:`repro.checks` (argument validators), :mod:`repro.io` (bounded, atomic file reading
and writing), :mod:`repro.data` (the datasets: where they are, what they hash to),
:mod:`repro.processes` (child processes that end with their parent).

Above them: :mod:`repro.experiments` (one registered function per figure or
measurement), :mod:`repro.claims` (each claim of the papers against its figure),
:mod:`repro.bench` (benchmarks), :mod:`repro.ui` (the panels and the apps) and
:mod:`repro.cli`, the ``repro`` command (``repro list``, ``repro run NAME``, ``repro all``,
``repro claims``, ``repro bench``, ``repro data``, ``repro app``).
"""

__version__ = "0.1.0"
