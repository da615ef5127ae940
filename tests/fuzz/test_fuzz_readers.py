"""The file readers against seeded mutants (issue 9, section 3).

Every reader of a file a user may hand to repro -- :func:`repro.motion.read_bvh` (then
forward kinematics, ``write_bvh`` and reading that back), ``read_asf`` / ``read_amc`` /
``read_asf_amc``, :func:`repro.blendshapes.faces.obj.read_obj`, glTF faces
(:func:`repro.blendshapes.faces.gltf.read_gltf` on ``.gltf`` files beside their buffer,
:func:`repro.blendshapes.load_model` on ``.glb`` files, then posing the model),
the ICT ``.npz`` cache check (:func:`repro.blendshapes.faces.ict.read_cache`, what ``load_ict``
runs before using a cache), :meth:`MotionDatabase.load` and the figure manifest
(``figures/manifest.json`` as :func:`repro.experiments.registry.run_many` reads, merges
and rewrites it) -- gets mutants of small real and hand-made seed files
(:mod:`tests.fuzz.mutate`).  Each input runs in a worker process with an address-space
limit (``RLIMIT_AS``, 2 GiB) and a 10 s time limit (:mod:`tests.fuzz.harness`).  What is
asserted, for every input:

* it loads, and every float of the result (and of the forward kinematics / the posed
  face) is finite (for OBJ also: every coordinate / vertex index it took is a plain ASCII
  number, not ``1_0``; for BVH also: what ``write_bvh`` wrote of it reads back),
* or it raises a :class:`repro.errors.ReproError`;
* never another exception (``MemoryError``, ``RecursionError``, ``KeyError`` ...), never a
  RuntimeWarning from repro, never a killed worker, never a timeout.

Also: a missing path, a folder, an empty file (and for the manifest, an output folder
that is a file).  A target stops after 3 timeouts (each costs 10 s and a restart).

The unmutated seeds must load (otherwise the fuzzer would only test error paths).
Deterministic: mutant ``n`` of a target is a function of ``n`` only.  About 1,300 mutants
by default (about 35 s of pytest on a loaded 2-core machine, load average 3; about 25 s
idle); ``REPRO_FUZZ_N=10000`` runs ~10,000 (split over the targets the same way).  A
failure names the code under test and prints, per distinct signature, the seed, the
mutation and where the offending input was saved (``REPRO_FUZZ_SAVE`` or a pytest
temporary folder), with the command that replays it.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from tests.fuzz import harness
from tests.fuzz.mutate import FORMATS, mutant

pytestmark = pytest.mark.fuzz

#: Share of the mutants per target (the BVH reader is the most used and the richest format).
WEIGHTS = {"bvh": 250, "asf": 150, "amc": 150, "obj": 150, "gltf": 60, "glb": 120, "ict_cache": 110, "db": 130,
           "manifest": 150}
DEFAULT_TOTAL = sum(WEIGHTS.values())


def n_mutants(target: str) -> int:
    total = int(os.environ.get("REPRO_FUZZ_N", DEFAULT_TOTAL))
    return max(1, round(total * WEIGHTS[target] / DEFAULT_TOTAL))


@pytest.fixture(scope="module")
def worker(tmp_path_factory):
    w = harness.new_worker(tmp_path_factory.mktemp("fuzz-worker"))
    w.start()
    yield w
    w.stop()


@pytest.fixture(scope="module")
def save_dir(tmp_path_factory) -> Path:
    d = os.environ.get("REPRO_FUZZ_SAVE")
    return Path(d) if d else tmp_path_factory.mktemp("fuzz-failures")


# ------------------------------------------------------------------ the harness itself
def test_mutants_are_deterministic_and_change_the_input():
    seed = harness.TINY_BVH
    a = [mutant(seed, "bvh", n) for n in range(200)]
    assert a == [mutant(seed, "bvh", n) for n in range(200)]
    assert sum(d != seed for d, _, _ in a) >= 190
    assert any(s.endswith(".gz") for _, s, _ in a)
    assert len({d for d, _, _ in a}) >= 180
    for fmt in FORMATS:
        data = harness.tiny_ict_cache()[0] if fmt == "npz" else seed
        assert mutant(data, fmt, 7) == mutant(data, fmt, 7)


#: What the harness must make of each misbehaviour of a worker (``worker.py``'s selftest target).
MISBEHAVIOURS = [
    ("ok", "ok", False),
    ("repro", "repro_error", False),
    ("value", "error", True),
    ("alloc", "error", True),  # a MemoryError under RLIMIT_AS, not the machine's memory
    ("nan", "nonfinite", True),
    ("kill", "crash", True),
    ("sleep", "timeout", True),
]


def test_harness_classifies_every_misbehaviour(tmp_path):
    p = tmp_path / "mode.txt"
    with harness.new_worker(tmp_path, time_limit=3.0) as w:
        assert w.ready["maxrss_kb"] * 1024 < harness.RLIMIT_AS / 2  # headroom under the limit after imports
        for mode, outcome, bad in MISBEHAVIOURS:
            p.write_text(mode)
            o = w.run("selftest", str(p))
            assert (o.outcome, o.bad) == (outcome, bad), (mode, o)
            if mode == "alloc":
                assert "MemoryError" in o.type
        assert w.restarts == 2  # replaced after the kill and the timeout ...
        p.write_text("ok")
        assert w.run("selftest", str(p)).outcome == "ok"  # ... and serves on


# ------------------------------------------------------------------ the readers
@pytest.mark.parametrize("target", list(harness.TARGETS))
def test_reader_survives_mutants(target, worker, save_dir):
    n = n_mutants(target)
    failures, stats = harness.run_target(target, n, save_dir, worker=worker, max_timeouts=3)
    if failures:
        by_sig: dict[str, list] = {}
        for f in failures:
            by_sig.setdefault(f.outcome.signature(target), []).append(f)
        lines = [f"{len(failures)} of {stats['n']} {target} inputs ({harness.READERS[target]}) neither loaded with "
                 f"finite values nor raised a ReproError ({len(by_sig)} distinct signatures; inputs saved under "
                 f"{save_dir / target}):"]
        for sig, fs in sorted(by_sig.items(), key=lambda kv: -len(kv[1])):
            lines.append(f"\n* {sig}  (x{len(fs)})\n  " + fs[0].report().replace("\n", "\n  "))
        if "stopped_after" in stats:
            lines.append(f"\n(stopped after mutant {stats['stopped_after']}: {stats['timeouts']} timeouts or crashes)")
        pytest.fail("\n".join(lines), pytrace=False)
    assert stats["n"] == n + len(stats["seeds"]) + stats["specials"]
