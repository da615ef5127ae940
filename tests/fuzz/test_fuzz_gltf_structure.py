"""The glTF reader against structural mutants (issue 23, section 8).

Mutants of the glTF fixtures' JSON (:mod:`tests.fuzz.gltf_structure`: accessor aliasing and
counts, zero-filled accessors, sparse accessors, bufferView offsets/lengths/strides, buffer
``uri``s with ``..``, percent-encoding, absolute paths, symlinks, FIFOs and folders, node,
mesh, primitive and target counts) are read by :func:`repro.blendshapes.faces.gltf.read_gltf` in a
worker process (:mod:`tests.fuzz.harness`'s, with :mod:`tests.fuzz.gltf_structure_worker`'s
extra target) under an address-space limit (``RLIMIT_AS``, 2 GiB) and a 10 s time limit.
For every mutant:

* it loads with finite values, or raises a :class:`repro.errors.ReproError`; never another
  exception, never a killed worker, never a timeout (a FIFO that hangs, 100,000 nodes);
* the read's peak resident memory stays under :data:`PEAK_LIMIT`;
* a mutant whose buffer names a file outside its folder (``..``, ``%2e%2e``, an absolute
  path, a symlink out, ``/dev/zero``) is refused, and no model ever holds the positions of
  the sentinel buffer planted outside the folder.

Deterministic (mutant ``n`` is a function of ``n``).  ``REPRO_FUZZ_GLTF_N`` sets the number
of mutants (default :data:`DEFAULT_N`, about 20-35 s on a loaded 2-core machine).
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest

from tests.fuzz import gltf_structure as gs
from tests.fuzz import harness

pytestmark = pytest.mark.fuzz

DEFAULT_N = 120
#: Resident memory one read may add: the reader's cap for a small file is 64 MiB of vertex data
#: (gltf.MODEL_BYTES_FLOOR); the rest is slack for pygltflib's objects and numpy temporaries.
PEAK_LIMIT = 384 << 20
STRUCTURE_WORKER = Path(gs.__file__).with_name("gltf_structure_worker.py")


class StructureWorker(harness.Worker):
    """The harness's worker, started on ``gltf_structure_worker.py`` (the same protocol and limits)."""

    def start(self) -> dict:
        saved = harness.WORKER
        harness.WORKER = STRUCTURE_WORKER
        try:
            return super().start()
        finally:
            harness.WORKER = saved


@pytest.fixture(scope="module")
def worker(tmp_path_factory):
    work = tmp_path_factory.mktemp("fuzz-gltf-structure")
    w = StructureWorker(harness.worker_context(work) | {"peak_limit": PEAK_LIMIT}, log_dir=str(work))
    w.start()
    yield w
    w.stop()


def test_structure_mutants_are_deterministic_and_cover_the_mutations(tmp_path):
    a = [gs.structure_mutant(n, 3, tmp_path / gs.SENTINEL_NAME) for n in range(60)]
    b = [gs.structure_mutant(n, 3, tmp_path / gs.SENTINEL_NAME) for n in range(60)]
    assert [(s, d, e) for s, _, _, d, e in a] == [(s, d, e) for s, _, _, d, e in b]
    kinds = {part.split(":")[0] for *_, d, _ in a for part in d.split("; ")}
    assert {"alias", "zero_fill", "count", "sparse", "view", "uri", "nodes", "meshes", "targets", "long_list"} <= kinds
    assert any(e for *_, e in a) and not all(e for *_, e in a)


def test_the_sentinel_would_be_seen(tmp_path, worker):
    """The check can fail: the face seed with its own buffer swapped for the sentinel's bytes gives sentinel positions."""
    (tmp_path / "case").mkdir()
    name, doc, files = gs.seeds()[0]
    assert name == "face"
    ok = worker.run("gltf_structure", str(gs.lay_out(tmp_path / "case", doc, files)))
    assert ok.outcome == "ok", ok
    files = {k: gs.sentinel_bytes() for k in files}  # inside the folder: allowed, and recognisable
    o = worker.run("gltf_structure", str(gs.lay_out(tmp_path / "case", doc, files)))
    assert (o.outcome, o.type) == ("wrong", "WrongResult") and "sentinel" in o.message


def test_gltf_reader_survives_structure_mutants(tmp_path, worker):
    n_total = int(os.environ.get("REPRO_FUZZ_GLTF_N", DEFAULT_N))
    (tmp_path / gs.SENTINEL_NAME).write_bytes(gs.sentinel_bytes())
    folder = tmp_path / "case"
    depth = len(Path(os.path.realpath(folder)).parts) - 1
    failures, outcomes, escaped = [], {}, 0
    for n in range(n_total):
        if folder.exists():
            shutil.rmtree(folder)
        seed, doc, files, desc, escapes = gs.structure_mutant(n, depth, tmp_path / gs.SENTINEL_NAME)
        path = gs.lay_out(folder, doc, files)
        o = worker.run("gltf_structure", str(path))
        outcomes[o.outcome] = outcomes.get(o.outcome, 0) + 1
        escaped += escapes
        bad = o.bad or (escapes and o.outcome != "repro_error")
        if bad:
            saved = tmp_path / "failures" / f"n{n}"
            shutil.copytree(folder, saved, symlinks=True, ignore=lambda d, names: [x for x in names if x == "pipe.bin"])
            failures.append(f"n={n} seed {seed!r}: {desc[:200]}\n  -> {o.outcome} in {o.stage or '?'}: {o.type}: "
                            f"{o.message[:300]}{' (it names a file outside its folder: must be refused)' if escapes else ''}"
                            f"\n  saved under {saved}")
    assert not failures, f"{len(failures)} of {n_total} glTF structure mutants misbehaved:\n" + "\n".join(failures)
    assert outcomes.get("ok", 0) >= 5 and outcomes.get("repro_error", 0) >= n_total // 3, outcomes
    assert escaped >= 5
