"""Fuzz worker: reads many inputs of one target, in a process with a memory limit.

Usage: ``python worker.py CONTEXT_JSON`` (started by :mod:`tests.fuzz.harness`).
Requests on stdin, one JSON object a line: ``{"target": "bvh", "path": "..."}``.  Replies on the
original stdout (the library's own prints go to stderr), one JSON object a line:

* ``{"outcome": "ok"}`` -- loaded, every float of the result finite;
* ``{"outcome": "repro_error", "type": ..., "message": ...}`` -- a ReproError: fine;
* ``{"outcome": "error", "type": ..., "message": ..., "traceback": ...}`` -- any other
  exception (MemoryError included): a defect;
* ``{"outcome": "nonfinite", "message": ...}`` -- loaded, but with a NaN/inf value.

The first reply (``{"outcome": "ready", ...}``) comes after the imports, under the
memory limit (``RLIMIT_AS``, bytes in the context's ``"rlimit_as"``).
"""

from __future__ import annotations

import dataclasses
import json
import os
import re
import resource
import sys
import tempfile
import traceback
import warnings


def _limit(nbytes: int) -> None:
    if nbytes:
        resource.setrlimit(resource.RLIMIT_AS, (nbytes, nbytes))


class NonFinite(Exception):
    pass


def check_finite(obj, where: str = "result", depth: int = 0, seen=None, skip=frozenset(), public_only: bool = False) -> None:
    """Raise :class:`NonFinite` naming the first NaN/inf float found in ``obj``'s data (pandas tables too).

    Not under the dict keys / attribute / column names in ``skip`` (nor :data:`INFINITE_OK`
    attributes); ``public_only`` skips ``_private`` attributes of repro objects (the argument
    fuzzer's rule: a cache may hold what the result does not).  The one walker of both fuzzers.
    """
    import numpy as np

    seen = set() if seen is None else seen
    if id(obj) in seen or depth > 8:
        return
    seen.add(id(obj))

    def walk(x, at):
        check_finite(x, at, depth + 1, seen, skip, public_only)

    mod = type(obj).__module__ or ""
    if mod.startswith("pandas"):
        if hasattr(obj, "select_dtypes"):  # DataFrame
            for col in obj.columns:
                if col not in skip:
                    walk(obj[col].to_numpy(), f"{where}[{col!r}]")
            return
        if hasattr(obj, "to_numpy"):
            walk(obj.to_numpy(), where)
            return
    if isinstance(obj, np.ndarray):
        if obj.dtype.kind in "fc":
            bad = ~np.isfinite(obj)
            if bad.any():
                idx = np.argwhere(bad)[0] if obj.ndim else ()
                raise NonFinite(f"{where}{list(map(int, idx))} = {obj[tuple(idx)]!r} (shape {obj.shape})")
        elif obj.dtype.kind == "O":
            for i, x in enumerate(obj.reshape(-1)[:1000]):
                walk(x, f"{where}[{i}]")
        return
    if isinstance(obj, (float, complex, np.floating, np.complexfloating)):
        if not np.isfinite(obj):
            raise NonFinite(f"{where} = {obj!r}")
        return
    if isinstance(obj, (str, bytes, int, bool, type(None), np.integer, np.bool_)):
        return
    if isinstance(obj, dict):
        for k, v in list(obj.items())[:10000]:
            if k not in skip:
                walk(v, f"{where}[{k!r}]")
        return
    if isinstance(obj, (list, tuple, set, frozenset)):
        for i, v in enumerate(list(obj)[:10000]):
            walk(v, f"{where}[{i}]")
        return
    if mod.startswith("repro"):
        fields = dict(getattr(obj, "__dict__", {}))
        if dataclasses.is_dataclass(obj):
            fields.update((f.name, getattr(obj, f.name, None)) for f in dataclasses.fields(obj))
        for k, v in fields.items():
            if k not in INFINITE_OK and k not in skip and not (public_only and k.startswith("_")):
                walk(v, f"{where}.{k}")


#: Attributes where an infinite value is legitimate: ASF joint limits ``(-inf inf)``; the search index's
#: per-cluster radius of a semantics, inf where the cluster holds no pose of it (a bound that prunes nothing:
#: :class:`repro.motion.search.index.RetrievalIndex`).
INFINITE_OK = {"limits", "radius"}


def _peak_rss_kb() -> int:
    """This process's peak resident set (KiB) since it was exec'd: ``VmHWM`` where /proc has it.
    ``ru_maxrss`` is not that on Linux: exec keeps the peak of the memory it replaces, which after
    subprocess's vfork is the parent's (the test session's, over 1 GiB late in a full run)."""
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1])
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss


def _registry_module():
    import importlib

    return importlib.import_module("repro.experiments.registry")  # the package re-exports a registry() function


class WrongResult(Exception):
    """The input loaded, but it should not have (a malformed number taken as a value ...)."""


_STRICT_FLOAT = re.compile(rb"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")
_STRICT_INDEX = re.compile(rb"[-+]?\d+")


def _strict_obj_numbers(path) -> None:
    """An oracle for read_obj: every coordinate of a ``v`` line and vertex index of an ``f`` line it accepted
    is a plain ASCII number (Python's float()/int() also take ``1_0``, ``\u0661`` (Arabic-Indic one), ...)."""
    import gzip

    with (gzip.open if str(path).endswith(".gz") else open)(path, "rb") as fh:
        raw = fh.read()
    for i, ln in enumerate(raw.replace(b"\r\n", b"\n").replace(b"\r", b"\n").split(b"\n")):
        tok = ln.split(b"#", 1)[0].split()
        if tok[:1] == [b"v"]:
            bad = [t for t in tok[1:4] if not _STRICT_FLOAT.fullmatch(t)]
        elif tok[:1] == [b"f"]:
            # only the vertex index is used (``v/vt/vn``: the texture and normal parts are ignored)
            bad = [t for t in tok[1:] if not _STRICT_INDEX.fullmatch(t.split(b"/", 1)[0])]
        else:
            continue
        if bad:
            raise WrongResult(f"line {i + 1}: accepted the malformed number {bad[0][:40]!r} in {ln[:80]!r}")


class RoundTripError(Exception):
    """A file the library wrote itself (from what it had just read) could not be read back."""


# ------------------------------------------------------------------ targets
class Targets:
    def __init__(self, ctx: dict):
        self.ctx = ctx
        self.tmp = tempfile.mkdtemp(prefix="repro-fuzz-worker-")
        import atexit
        import shutil

        atexit.register(shutil.rmtree, self.tmp, True)  # (not after a kill: under the system temp folder)
        self._skels = {}
        self.stage = ""

    # BVH: read, forward kinematics, write back and read again
    def bvh(self, path, req=None):
        from repro.errors import ReproError
        from repro.motion import read_bvh, write_bvh

        self.stage = "read_bvh"
        m = read_bvh(path)
        check_finite(m, "motion")
        check_finite(m.fps, "motion.fps")
        self.stage = "global_positions"
        check_finite(m.global_positions(), "global_positions()")
        out = os.path.join(self.tmp, "again.bvh")
        self.stage = "write_bvh"
        try:
            write_bvh(m, out, overwrite=True)
        except ReproError:
            return
        self.stage = "read_bvh(written)"
        try:
            again = read_bvh(out)
        except ReproError as exc:
            raise RoundTripError(f"write_bvh output unreadable: {type(exc).__name__}: {exc}") from exc
        if again.n_frames != m.n_frames or again.n_joints != m.n_joints:
            raise RoundTripError(f"write_bvh/read_bvh changed the size: {m.n_frames}x{m.n_joints} -> "
                                 f"{again.n_frames}x{again.n_joints}")

    def _amc_motion(self, m):
        check_finite(m, "motion")
        check_finite(m.fps, "motion.fps")
        self.stage = "global_positions"
        check_finite(m.global_positions(), "global_positions()")

    # ASF mutated, read with a good AMC excerpt
    def asf(self, path, req):
        from repro.motion import read_amc, read_asf

        self.stage = "read_asf"
        skel = read_asf(path)
        check_finite(skel, "skeleton")
        check_finite(skel.offsets(), "skeleton.offsets()")
        check_finite(skel.axis_quaternions(), "skeleton.axis_quaternions()")
        self.stage = "read_amc"
        self._amc_motion(read_amc(req["amc"], skel))

    # AMC mutated, read with the good ASF
    def amc(self, path, req):
        from repro.motion import read_asf, read_asf_amc

        from repro.motion import read_amc

        if req["asf"] not in self._skels:
            self._skels[req["asf"]] = read_asf(req["asf"])
        skel = self._skels[req["asf"]]

        self.stage = "read_amc"
        self._amc_motion(read_amc(path, skel))
        self.stage = "read_asf_amc"
        self._amc_motion(read_asf_amc(req["asf"], path))

    def obj(self, path, req=None):
        import numpy as np

        from repro.blendshapes.faces.obj import read_obj

        self.stage = "read_obj"
        v, f = read_obj(path)
        check_finite(v, "vertices")
        if v.ndim != 2 or v.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3:
            raise NonFinite(f"shapes {v.shape}, {f.shape}: expected (n, 3) and (F, 3)")
        if f.size and (f.min() < 0 or f.max() >= len(v)):
            raise NonFinite(f"face index outside 0..{len(v) - 1}: {f.min()}..{f.max()}")
        if not np.issubdtype(f.dtype, np.integer):
            raise NonFinite(f"faces of dtype {f.dtype}")
        self.stage = "read_obj (strict number check)"
        _strict_obj_numbers(path)

    def db(self, path, req=None):
        from repro.motion.database.clips import MotionDatabase

        self.stage = "MotionDatabase.load"
        db = MotionDatabase.load(path)
        check_finite(db, "db")
        self.stage = "use of the loaded database"
        len(db)
        db.summary()
        for i in range(min(db.n_clips, 2)):
            check_finite(db.trajectory(i), f"db.trajectory({i})")
            check_finite(db.motion(i).global_positions(), f"db.motion({i}).global_positions()")

    def ict_cache(self, path, req=None):
        from repro.blendshapes.faces import ict

        # the small seed cache stands for the ICT mesh: sizes patched to its own
        ict.ICT_N_VERTICES, ict.ICT_N_TRIANGLES = self.ctx["ict_sizes"]
        self.stage = "ict.read_cache"
        # the documented check load_ict makes before using a cache file: arrays, or a DataError saying
        # what is wrong (load_ict then rebuilds with a CacheWarning)
        arrays = ict.read_cache(path, tuple(self.ctx["ict_shapes"]))
        check_finite(arrays, "cache arrays")

    def _gltf_model(self, m):
        import numpy as np

        check_finite(m, "model")
        self.stage = "use of the model"
        check_finite(m.pose(np.ones(m.n_shapes)), "model.pose(ones)")
        for name in list(m.slider_names)[:8]:
            check_finite(m.weights({name: 1.0}), f"model.weights({{{name!r}: 1}})")

    # glTF: a mutated .gltf (its .bin beside it) through read_gltf; a mutated .glb through load_model
    def gltf(self, path, req=None):
        from repro.blendshapes.faces.gltf import read_gltf

        self.stage = "read_gltf"
        self._gltf_model(read_gltf(path))

    def glb(self, path, req=None):
        from pathlib import Path

        from repro.blendshapes import load_model

        self.stage = "load_model"
        self._gltf_model(load_model(Path(path)))

    def manifest(self, path, req=None):
        import shutil

        registry = _registry_module()

        self._register_tiny()
        out = os.path.join(self.tmp, "figs")
        if os.path.isdir(out):
            shutil.rmtree(out)
        elif os.path.exists(out):
            os.unlink(out)
        if req and req.get("out_is_file"):  # --out naming a file
            with open(out, "w") as fh:
                fh.write("not a folder\n")
        else:
            os.makedirs(out)
            shutil.copy(self.ctx["tiny_csv"], os.path.join(out, "fuzz_tiny.csv"))
            if os.path.isdir(path):  # the special inputs: manifest.json is a folder, or absent
                os.makedirs(os.path.join(out, registry.MANIFEST))
            elif os.path.exists(path):
                shutil.copy(path, os.path.join(out, registry.MANIFEST))
        self.stage = "run_many"
        status = registry.run_many(["fuzz_tiny"], out)
        if status.get("fuzz_tiny") not in ("ran", "cached"):
            raise NonFinite(f"tiny figure status {status}")
        self.stage = "read the rewritten manifest"
        if req and req.get("out_is_file"):
            raise NonFinite(f"run_many into a file {out!r} did not fail")
        with open(os.path.join(out, registry.MANIFEST)) as fh:
            json.load(fh)

    def _register_tiny(self):
        registry = _registry_module()

        if "fuzz_tiny" in registry._REGISTRY:
            return
        import pandas as pd

        registry.registry()  # the real ones first

        @registry.experiment("fuzz_tiny", "a one-row table for the manifest fuzzer", paper="fuzz", data=())
        def fuzz_tiny(quick: bool = False):
            return registry.Result(table=pd.DataFrame({"x": [1]}))

        # not manifest readers, and slow (git, notebooks, hashing the code, package metadata): constants
        registry._git_commit = lambda: "fuzz"
        registry._notebooks_using = lambda name: []
        registry._code_fingerprint = lambda: "0" * 64
        versions = registry._versions()
        registry._versions = lambda: dict(versions)

    def selftest(self, path, req=None):
        """Misbehaviours on demand, so the tests can check that the harness classifies each one."""
        import signal
        import time

        import numpy as np

        from repro.errors import DataError

        mode = open(path).read().strip()
        self.stage = f"selftest {mode}"
        if mode == "repro":
            raise DataError("a library error")
        if mode == "value":
            raise ValueError("a bare error")
        if mode == "alloc":
            return np.ones(int(self.ctx["rlimit_as"]) + (1 << 30), dtype=np.uint8)
        if mode == "sleep":
            time.sleep(3600)
        if mode == "kill":
            os.kill(os.getpid(), signal.SIGKILL)
        if mode == "nan":
            check_finite({"x": np.array([1.0, np.nan])}, "result")

    def manifest_seed(self):
        """The manifest a fresh run of the tiny figure writes (the seed of the manifest target)."""
        registry = _registry_module()

        self._register_tiny()
        out = os.path.join(self.tmp, "seed")
        os.makedirs(out, exist_ok=True)
        registry.run_many(["fuzz_tiny"], out)
        with open(os.path.join(out, "fuzz_tiny.csv"), "rb") as fh:
            csv = fh.read()
        with open(os.path.join(out, registry.MANIFEST), "rb") as fh:
            return fh.read(), csv


def main() -> None:
    ctx = json.loads(sys.argv[1])
    proto = os.fdopen(os.dup(1), "w", buffering=1)
    os.dup2(2, 1)  # library prints cannot corrupt the protocol
    sys.stdout = sys.stderr
    import faulthandler

    faulthandler.enable()
    _limit(int(ctx.get("rlimit_as", 0)))

    def reply(**kw):
        proto.write(json.dumps(kw) + "\n")
        proto.flush()

    try:
        import numpy  # noqa: F401

        import pygltflib  # noqa: F401 - (2 s to import: before the first input's time limit)

        import repro.blendshapes.faces.gltf  # noqa: F401
        import repro.blendshapes.faces.ict  # noqa: F401
        import repro.experiments.registry  # noqa: F401
        import repro.motion  # noqa: F401
        from repro.errors import ReproError
    except BaseException as exc:  # noqa: BLE001
        reply(outcome="broken", message=f"imports failed: {type(exc).__name__}: {exc}")
        return
    # the test suite's policy (pyproject filterwarnings): a RuntimeWarning from repro is an error
    warnings.filterwarnings("ignore", category=Warning)
    warnings.filterwarnings("error", category=RuntimeWarning, module=r"repro\..*")
    targets = Targets(ctx)
    usage = _peak_rss_kb()
    import repro

    reply(outcome="ready", maxrss_kb=usage, repro_file=repro.__file__)
    for line in sys.stdin:
        req = json.loads(line)
        if req.get("op") == "manifest_seed":
            data, csv = targets.manifest_seed()
            reply(outcome="seed", data=data.decode(), csv=csv.decode())
            continue
        targets.stage = ""
        try:
            getattr(targets, req["target"])(req["path"], req)
        except ReproError as exc:
            reply(outcome="repro_error", type=type(exc).__name__, message=str(exc)[:2000], stage=targets.stage)
        except NonFinite as exc:
            reply(outcome="nonfinite", type="NonFinite", message=str(exc)[:2000], stage=targets.stage)
        except WrongResult as exc:
            reply(outcome="wrong", type="WrongResult", message=str(exc)[:2000], stage=targets.stage)
        except BaseException as exc:  # noqa: BLE001 - the point: anything else is a defect
            tb = "".join(traceback.format_exception(exc))
            if len(tb) > 6000:
                tb = tb[:2000] + "\n[...]\n" + tb[-4000:]
            name = type(exc).__qualname__
            if type(exc).__module__ not in ("builtins", None):
                name = f"{type(exc).__module__}.{name}"
            try:
                msg = str(exc)[:2000]
            except BaseException:  # noqa: BLE001
                msg = "<str() failed>"
            memory = isinstance(exc, MemoryError)
            exc = None  # drop frames (and big arrays) before replying
            reply(outcome="error", type=name, memory=memory, message=msg, stage=targets.stage, traceback=tb[-6000:])
        else:
            reply(outcome="ok")


if __name__ == "__main__":
    main()
