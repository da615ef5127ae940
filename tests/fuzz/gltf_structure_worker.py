"""The fuzz worker of :mod:`tests.fuzz.worker` with one more target, ``gltf_structure``.

Started by :class:`tests.fuzz.test_fuzz_gltf_structure.StructureWorker` in place of
``worker.py`` (same protocol, same ``RLIMIT_AS``).  The target reads a mutated ``.gltf`` with
:func:`repro.blendshapes.faces.gltf.read_gltf`, then checks, besides what the ``gltf`` target checks
(finite values, the model posable):

* the peak resident memory of the read (``VmHWM``, reset through ``/proc/self/clear_refs``
  before it) stayed under the context's ``peak_limit`` bytes, whether it loaded or raised;
* a model built holds no position of the sentinel file planted outside the folder
  (:data:`tests.fuzz.gltf_structure.SENTINEL_VALUE`): no read left the folder.
"""

from __future__ import annotations

import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import worker  # noqa: E402  (tests/fuzz/worker.py, run as a script like this one)

SENTINEL_VALUE = 4242.0


def _hwm_kb() -> int:
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith("VmHWM:"):
                return int(line.split()[1])
    return 0


def _reset_peak() -> bool:
    try:
        with open("/proc/self/clear_refs", "w") as fh:
            fh.write("5")  # resets VmHWM to the current resident set
        return True
    except OSError:
        return False


class StructureTargets(worker.Targets):
    def gltf_structure(self, path, req=None):
        import numpy as np

        from repro.blendshapes.faces.gltf import read_gltf
        from repro.errors import ReproError

        limit = int(self.ctx.get("peak_limit", 0))
        measured = limit and _reset_peak()
        base = _hwm_kb() if measured else 0
        self.stage = "read_gltf"
        try:
            m = read_gltf(path)
        except ReproError:
            self._check_peak(measured, base, limit)
            raise
        self._check_peak(measured, base, limit)
        if np.any(np.abs(m.f0) >= SENTINEL_VALUE / 2):
            raise worker.WrongResult(f"the model holds the sentinel's positions ({SENTINEL_VALUE}): a buffer was read "
                                     "from outside the glTF file's folder")
        self._gltf_model(m)

    def _check_peak(self, measured, base, limit):
        if measured:
            grew = (_hwm_kb() - base) * 1024
            if grew > limit:
                raise worker.WrongResult(f"reading took {grew / 2**20:.0f} MiB of resident memory, more than "
                                         f"{limit / 2**20:.0f} MiB")


if __name__ == "__main__":
    worker.Targets = StructureTargets
    worker.main()
