"""Seeds, the worker pool and the campaign loop of the reader fuzzer.

``python -m tests.fuzz.harness run --n 1000 --out DIR`` runs a long campaign (every
target, ``--n`` mutants each), minimises one input per distinct failure signature
and writes them with a README into ``DIR``; ``python -m tests.fuzz.harness replay
TARGET FILE [--asf A | --amc M]`` runs one saved input through the worker and prints
the outcome (the traceback for a defect).
"""

from __future__ import annotations

import dataclasses
import gzip
import json
import os
import re
import select
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from tests.fuzz.mutate import FORMATS, mutant

WORKER = Path(__file__).with_name("worker.py")
REPO = Path(__file__).resolve().parents[2]
#: Address-space limit of a worker; the imports (numpy, scipy, pandas, repro) take ~0.4 GiB.
RLIMIT_AS = 2 << 30
#: Seconds one input may take (enforced by the parent, which kills the worker).
TIME_LIMIT = 10.0
READY_LIMIT = 60.0

#: target -> mutated format (the readers' targets first; ``db`` and ``manifest`` last)
TARGETS = {
    "bvh": "bvh",
    "asf": "asf",
    "amc": "amc",
    "obj": "obj",
    "gltf": "gltf",
    "glb": "glb",
    "ict_cache": "npz",
    "db": "npz",
    "manifest": "json",
}
#: The code each target exercises (named in a failing test's message).
READERS = {
    "bvh": "repro/motion/io/bvh.py read_bvh / write_bvh, repro/motion/core/motion.py",
    "asf": "repro/motion/io/asf.py read_asf, then repro/motion/io/asfamc.py read_amc",
    "amc": "repro/motion/io/asfamc.py read_amc / read_asf_amc",
    "obj": "repro/blendshapes/faces/obj.py read_obj",
    "gltf": "repro/blendshapes/faces/gltf.py read_gltf",
    "glb": "repro/blendshapes load_model -> gltf.py read_gltf",
    "ict_cache": "repro/blendshapes/faces/ict.py read_cache -> repro/io.py read_npz",
    "db": "repro/motion/database/clips.py MotionDatabase.load",
    "manifest": "repro/experiments/registry.py run_many (figures/manifest.json)",
}
#: The glTF fixtures (made by scripts/make_gltf_fixtures.py); a .gltf's buffer file is its partner.
GLTF_DIR = REPO / "tests" / "data" / "gltf"
GLB_SEEDS = ("face.glb", "face_quantized.glb", "face_sparse.glb", "face_meshopt.glb", "face_node.glb",
             "face_meshes.glb", "face_gltfpack.glb")
#: Files a target's inputs refer to by name, copied beside the inputs and the saved failures.
PARTNERS = {"gltf": ("face.bin",)}


@dataclasses.dataclass
class Seed:
    name: str
    data: bytes
    extra: dict = dataclasses.field(default_factory=dict)  # sent with each request (asf/amc partner path)


@dataclasses.dataclass
class Outcome:
    outcome: str  # ok | repro_error | error | nonfinite | wrong | timeout | crash
    type: str = ""
    message: str = ""
    traceback: str = ""
    seconds: float = 0.0
    stage: str = ""

    @property
    def bad(self) -> bool:
        return self.outcome not in ("ok", "repro_error")

    def signature(self, target: str) -> str:
        return f"{target} | {self.stage} | {self.outcome} | {self.type} | {message_head(self.message)}"

    def kind(self, target: str) -> str:
        """The coarse signature: target, stage, outcome, exception type (what one defect usually is)."""
        return f"{target} | {self.stage} | {self.outcome} | {self.type}"


def message_head(msg: str, n: int = 60) -> str:
    """The first line of a message with file names, quoted values and numbers generalised."""
    s = (msg or "").splitlines()[0] if msg else ""
    s = re.sub(r"(/[^\s:,'\"]+)+", "<path>", s)
    s = re.sub(r"'[^']*'|\"[^\"]*\"", "'…'", s)
    s = re.sub(r"b'…'", "'…'", s)
    s = re.sub(r"0x[0-9a-f]+", "0x…", s)
    s = re.sub(r"[-+]?\d[\d.eE+\-_]*", "N", s)
    s = re.sub(r"N [KMGT]iB", "N <size>", s)
    s = re.sub(r"\bline N\b", "line N", s)
    return s[:n]


# ------------------------------------------------------------------ the worker
class Worker:
    """One long-lived worker process (any target); restarted after a crash or a timeout."""

    def __init__(self, ctx: dict | None = None, *, rlimit_as: int = RLIMIT_AS,
                 time_limit: float = TIME_LIMIT, log_dir: str | None = None):
        self.ctx = dict(ctx or {}, rlimit_as=rlimit_as)
        self.time_limit = time_limit
        self.log_dir = log_dir or tempfile.mkdtemp(prefix="repro-fuzz-log-")
        self.proc: subprocess.Popen | None = None
        self._buf = b""
        self.restarts = 0

    def _child_tmp(self) -> str:
        """The child's temporary folder (its TMPDIR), under the log folder: a killed child leaves nothing elsewhere."""
        d = Path(self.log_dir) / "tmp"
        d.mkdir(exist_ok=True)
        return str(d)

    def start(self) -> dict:
        env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1", MKL_NUM_THREADS="1",
                   PYTHONPATH=os.pathsep.join([str(REPO)] + [p for p in [os.environ.get("PYTHONPATH")] if p]),
                   MPLBACKEND="Agg", REPRO_OFFLINE="1", PYTHONHASHSEED="0", TMPDIR=self._child_tmp())
        self.log = Path(self.log_dir) / f"worker-{self.restarts}.log"
        self._log_fh = open(self.log, "wb")
        self.proc = subprocess.Popen([sys.executable, str(WORKER), json.dumps(self.ctx)],
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=self._log_fh,
                                     cwd=REPO, env=env)
        self._buf = b""
        ready = self._reply(READY_LIMIT)
        if ready is None or ready.get("outcome") != "ready":
            tail = self.log.read_text(errors="replace")[-3000:]
            self.stop()
            raise RuntimeError(f"fuzz worker did not start: {ready}\n{tail}")
        if not Path(ready["repro_file"]).resolve().is_relative_to(REPO):
            self.stop()
            raise RuntimeError(f"the fuzz worker imported {ready['repro_file']}, not the checkout {REPO}")
        self.ready = ready
        return ready

    def stop(self) -> None:
        if self.proc is not None:
            if self.proc.poll() is None:
                self.proc.kill()  # our own child, by its handle
            self.proc.wait()
            for fh in (self.proc.stdin, self.proc.stdout):
                try:
                    fh.close()
                except OSError:
                    pass
            self._log_fh.close()
        self.proc = None

    def _reply(self, timeout: float) -> dict | None:
        deadline = time.monotonic() + timeout
        fd = self.proc.stdout.fileno()
        while b"\n" not in self._buf:
            left = deadline - time.monotonic()
            if left <= 0:
                return None
            r, _, _ = select.select([fd], [], [], left)
            if not r:
                return None
            chunk = os.read(fd, 1 << 16)
            if not chunk:
                return {"outcome": "eof"}
            self._buf += chunk
        line, self._buf = self._buf.split(b"\n", 1)
        return json.loads(line)

    def request(self, req: dict, timeout: float | None = None) -> dict | None:
        if self.proc is None or self.proc.poll() is not None:
            if self.proc is not None:
                self.stop()
                self.restarts += 1
            self.start()
        try:
            self.proc.stdin.write((json.dumps(req) + "\n").encode())
            self.proc.stdin.flush()
        except BrokenPipeError:
            return {"outcome": "eof"}
        return self._reply(self.time_limit if timeout is None else timeout)

    def run(self, target: str, path: str, extra: dict | None = None) -> Outcome:
        if self.proc is None or self.proc.poll() is not None:  # (re)start outside the input's time
            if self.proc is not None:
                self.stop()
                self.restarts += 1
            self.start()
        t0 = time.monotonic()
        rep = self.request(dict(extra or {}, target=target, path=str(path)))
        dt = time.monotonic() - t0
        if rep is None:
            self.stop()
            self.restarts += 1
            return Outcome("timeout", "Timeout", f"no answer within {self.time_limit:g} s", seconds=dt)
        if rep.get("outcome") == "eof":
            rc = self.proc.wait()
            tail = self.log.read_text(errors="replace")[-4000:]
            self.stop()
            self.restarts += 1
            kind = "killed by signal %d" % -rc if rc < 0 else f"exit status {rc}"
            return Outcome("crash", "WorkerDied", f"worker {kind}", traceback=tail, seconds=dt)
        out = Outcome(rep["outcome"], rep.get("type", ""), rep.get("message", ""), rep.get("traceback", ""), dt,
                      rep.get("stage", ""))
        return out

    def __enter__(self):
        self.start()
        return self

    def __exit__(self, *exc):
        self.stop()


# ------------------------------------------------------------------ seeds
TINY_BVH = b"""HIERARCHY
ROOT Hips
{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT Spine
  {
    OFFSET 0 5.2 0
    CHANNELS 3 Zrotation Xrotation Yrotation
    JOINT Head
    {
      OFFSET 0 4.1 0.5
      CHANNELS 3 Yrotation Xrotation Zrotation
      End Site
      {
        OFFSET 0 2 0
      }
    }
  }
  JOINT Leg
  {
    OFFSET 1.5 -1 0
    CHANNELS 3 Xrotation Yrotation Zrotation
    End Site
    {
      OFFSET 0 -8 0
    }
  }
}
MOTION
Frames: 3
Frame Time: 0.0083333
0 35.5 0 0 0 0 1.5 -2 3 10 20 30 -5 0 5
0.5 35.25 -0.25 1 2 3 1.25 -1.5 2.5 9 19 29 -4 1e-3 4
1 35 -0.5 2 4 6 1 -1 2 8 18 28 -3 0.002 3
"""

TINY_ASF = b""":version 1.10
:name tiny
:units
  mass 1.0
  length 0.45
  angle deg
:root
   order TX TY TZ RX RY RZ
   axis XYZ
   position 0 0 0
   orientation 0 0 0
:bonedata
  begin
     id 1
     name lfemur
     direction 0.34202 -0.939693 0
     length 6.92462
     axis 0 0 20  XYZ
    dof rx ry rz
    limits (-160.0 20.0)
           (-70.0 70.0)
           (-60.0 70.0)
  end
  begin
     id 2
     name ltibia
     direction 0 -1 0
     length 7.4
     axis 0 0 20 XYZ
    dof rx
    limits (-10.0 170.0)
  end
  begin
     id 3
     name lowerback
     direction 0 1 0
     length 2
     axis 0 0 0 XYZ
  end
:hierarchy
  begin
    root lfemur lowerback
    lfemur ltibia
  end
"""

TINY_AMC = b""":FULLY-SPECIFIED
:DEGREES
1
root 7.46593 15.9937 -36.7321 7.11356 1.31487 -3.66776
lfemur -40.6897 6.42258 -16.3516
ltibia 43.9106
2
root 7.46979 15.9909 -36.6099 6.97364 1.17677 -3.42769
lfemur -40.2 6.4 -16.1
ltibia 43.5
"""

TINY_OBJ = b"""# a handmade mesh
mtllib x.mtl
o tiny
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
v 0.5 0.5 1.25 1.0
vt 0 0
vt 1 0
vn 0 0 1
usemtl skin
s 1
f 1/1/1 2/2/1 3//1
f 1 3 4
f -5 -4 -1 -2
g other
f 2 3 5
"""


def _data_dir() -> Path | None:
    d = os.environ.get("REPRO_DATA_DIR")
    if d and Path(d).is_dir():
        return Path(d)
    staged = REPO.parent / "shared" / "data"
    return staged if staged.is_dir() else None


def _read(p: Path) -> bytes:
    return gzip.decompress(p.read_bytes()) if p.suffix == ".gz" else p.read_bytes()


def bvh_excerpt(data: bytes, frames: int = 4) -> bytes:
    """The hierarchy and the first ``frames`` frame lines of a BVH (``Frames:`` fixed)."""
    head, _, motion = data.partition(b"MOTION")
    lines = motion.replace(b"\r\n", b"\n").split(b"\n")
    out, body = [], []
    for ln in lines[1:]:
        if ln.startswith(b"Frames"):
            continue
        if ln.startswith(b"Frame Time"):
            out.append(ln)
            continue
        if ln.strip():
            body.append(ln)
    body = body[:frames]
    return head + b"MOTION\nFrames: %d\n" % len(body) + b"\n".join(out + body) + b"\n"


def amc_excerpt(data: bytes, frames: int = 3) -> bytes:
    """The header and the first ``frames`` frames of an AMC."""
    out, seen = [], 0
    for ln in data.split(b"\n"):
        if ln.strip().isdigit():
            seen += 1
            if seen > frames:
                break
        out.append(ln)
    return b"\n".join(out) + b"\n"


def obj_excerpt(data: bytes, n_lines: int = 2000) -> bytes:
    """The first ``n_lines`` lines of an OBJ, plus the faces that only use their vertices."""
    lines = data.split(b"\n")
    head = lines[:n_lines]
    nv = sum(1 for ln in head if ln.startswith(b"v "))
    faces = []
    for ln in lines[n_lines:]:
        if ln.startswith(b"f "):
            idx = [int(t.split(b"/")[0]) for t in ln.split()[1:]]
            if all(0 < i <= nv for i in idx):
                faces.append(ln)
                if len(faces) >= 300:
                    break
    return b"\n".join(head + faces) + b"\n"


def synthetic_bvh() -> bytes:
    """A short clip of the library's synthetic database, written by write_bvh."""
    from repro.motion import write_bvh
    from repro.motion.core.ops import cut
    from repro.motion.database.synthetic import synthetic_clip

    m, _ = synthetic_clip("kick_front", seed=0)
    with tempfile.TemporaryDirectory() as tmp:
        p = write_bvh(cut(m, 0, 5), Path(tmp) / "syn.bvh", precision=8)
        return p.read_bytes()


def tiny_database_npz() -> bytes:
    """``MotionDatabase.save`` of a two-clip database (a synthetic punch and its augmented copy)."""
    from repro.motion.database.augment import augment
    from repro.motion.database.clips import MotionDatabase, annotate
    from repro.motion.core.ops import resample
    from repro.motion.database.synthetic import synthetic_clip

    m, ann = synthetic_clip("punch", seed=0)
    m = resample(m, 30.0)
    clip = annotate(m, ann["hit_frame"] // 2, "right_fist", "punch", name="p0", hit_joint=ann["hit_joint"],
                    hit_where="end_site")
    db = augment(MotionDatabase.from_clips([clip]), 2, seed=0)
    with tempfile.TemporaryDirectory() as tmp:
        return db.save(Path(tmp) / "db.npz").read_bytes()


def tiny_ict_cache() -> tuple[bytes, dict]:
    """A small valid ICT cache (format, source and content hashes as ``ict._save_cache`` writes them),
    and the worker context that makes its sizes the ICT mesh's."""
    import numpy as np

    from repro.blendshapes.faces import ict

    rng = np.random.default_rng(0)
    shapes = list(ict.ICT_SHAPES[:2])
    f0 = rng.normal(size=(6, 3))
    arrays = {
        "f0": f0,
        "D": rng.normal(size=(18, 2)) * 0.1,
        "faces": np.array([[0, 1, 2], [0, 2, 3], [3, 4, 5]], dtype=np.int64),
        "names": np.array(shapes, dtype=str),
        "landmarks": rng.integers(0, 6, size=68),
        "format": np.array(ict._CACHE_FORMAT),
    }
    with tempfile.TemporaryDirectory() as tmp:
        p = Path(tmp) / "cache.npz"
        if not ict._save_cache(p, arrays, ict._source_hashes(tuple(shapes))):
            raise RuntimeError("could not write the tiny ICT cache")
        return p.read_bytes(), {"ict_sizes": [6, 3], "ict_shapes": shapes}


def seeds(target: str, work: Path, worker: Worker | None = None) -> list[Seed]:
    """The seed inputs of a target (hand-made ones always; real files when the data folder is there).

    Partner files (the AMC excerpt an ASF is read with, and the other way) are written
    into ``work``.
    """
    data = _data_dir()
    work.mkdir(parents=True, exist_ok=True)
    out: list[Seed] = []
    if target == "bvh":
        out.append(Seed("tiny.bvh", TINY_BVH))
        out.append(Seed("synthetic_kick_front.bvh", synthetic_bvh()))
        d = data / "mocap/formats/pybvh" if data else None
        if d and d.is_dir():
            for name in ("standard_skeleton.bvh", "rotation_first_root.bvh", "full_precision_frame_time.bvh",
                         "bvh_test1.bvh"):
                if (d / name).is_file():
                    out.append(Seed(f"pybvh/{name}", bvh_excerpt((d / name).read_bytes())))
    elif target in ("asf", "amc"):
        pairs = [("tiny", TINY_ASF, TINY_AMC)]
        d = data / "mocap/cmu/source" if data else None
        if d and (d / "07.asf.gz").is_file() and (d / "07_05.amc.gz").is_file():
            pairs.append(("cmu07", _read(d / "07.asf.gz"), amc_excerpt(_read(d / "07_05.amc.gz"))))
        for name, asf, amc in pairs:
            (work / f"{name}.asf").write_bytes(asf)
            (work / f"{name}.amc").write_bytes(amc)
            if target == "asf":
                out.append(Seed(f"{name}.asf", asf, {"amc": str(work / f"{name}.amc")}))
            else:
                out.append(Seed(f"{name}.amc", amc, {"asf": str(work / f"{name}.asf")}))
    elif target == "obj":
        out.append(Seed("tiny.obj", TINY_OBJ))
        p = data / "faces/ict/generic_neutral_mesh.obj.gz" if data else None
        if p and p.is_file():
            out.append(Seed("ict/generic_neutral_mesh.obj[:2000 lines]", obj_excerpt(_read(p))))
    elif target == "gltf":
        for name in PARTNERS["gltf"]:
            (work / name).write_bytes((GLTF_DIR / name).read_bytes())
        out.append(Seed("gltf/face.gltf", (GLTF_DIR / "face.gltf").read_bytes()))
    elif target == "glb":
        out.extend(Seed(f"gltf/{name}", (GLTF_DIR / name).read_bytes()) for name in GLB_SEEDS)
    elif target == "db":
        out.append(Seed("tiny_db.npz", tiny_database_npz()))
    elif target == "ict_cache":
        out.append(Seed("tiny_ict_cache.npz", tiny_ict_cache()[0]))
    elif target == "manifest":
        rep = worker.request({"op": "manifest_seed"}, timeout=READY_LIMIT)
        if not rep or rep.get("outcome") != "seed":
            raise RuntimeError(f"manifest seed: {rep}")
        out.append(Seed("figures/manifest.json", rep["data"].encode()))
    return out


def special_inputs(target: str, work: Path, seed: Seed) -> list[tuple]:
    """Paths that are not a good file: missing, a folder, empty (and for the manifest, ``--out`` a file).

    Items as the campaign loop takes them, the path in place of the data, numbers ``-2, -3, ...``.
    """
    suffix = FORMATS[TARGETS[target]]["suffix"]
    folder = work / f"a-folder{suffix}"
    folder.mkdir(exist_ok=True)
    (work / f"empty{suffix}").write_bytes(b"")
    items = [(seed, -2, work / f"does-not-exist{suffix}", suffix, "special: a path that does not exist"),
             (seed, -3, folder, suffix, "special: a folder"),
             (seed, -4, work / f"empty{suffix}", suffix, "special: an empty file")]
    if FORMATS[TARGETS[target]]["gz"]:
        (work / f"empty{suffix}.gz").write_bytes(b"")
        items.append((seed, -5, work / f"empty{suffix}.gz", suffix + ".gz", "special: an empty .gz file"))
    if target == "manifest":
        items.append((dataclasses.replace(seed, extra={"out_is_file": True}), -6, work / "unused.json", suffix,
                      "special: the output folder is a file"))
    return items


def worker_context(work: Path) -> dict:
    """What the worker's targets need besides the input (written into ``work``)."""
    work.mkdir(parents=True, exist_ok=True)
    ctx: dict = dict(tiny_ict_cache()[1])
    p = work / "fuzz_tiny.csv"
    p.write_text("x\n1\n")
    ctx["tiny_csv"] = str(p)
    return ctx


def new_worker(work: Path | None = None, **kw) -> Worker:
    """A worker (not started) with the context of every target."""
    work = Path(work or tempfile.mkdtemp(prefix="repro-fuzz-"))
    return Worker(worker_context(work), log_dir=str(work), **kw)


# ------------------------------------------------------------------ campaign
@dataclasses.dataclass
class Failure:
    target: str
    seed: str
    n: int
    description: str
    outcome: Outcome
    path: Path
    extra: dict

    def report(self) -> str:
        o = self.outcome
        return (f"[{self.target}] {o.outcome} in {o.stage or '?'}: {o.type}: {o.message[:300]}\n"
                f"  seed {self.seed!r}, mutant n={self.n}: {self.description[:400]}\n"
                f"  input saved as {self.path}\n"
                f"  replay: python -m tests.fuzz.harness replay {self.target} {self.path}"
                + "".join(f" --{k} {v}" for k, v in self.extra.items() if k in ("asf", "amc"))
                + ("" if "out_is_file" not in self.extra else "  (with the output folder a file)"))


def run_target(target: str, n_mutants: int, save_dir: Path, *, worker: Worker | None = None, start: int = 0,
               time_budget: float | None = None, max_timeouts: int | None = None,
               progress=None) -> tuple[list[Failure], dict]:
    """Run the seeds and ``n_mutants`` mutants of ``target``; every bad outcome saved under ``save_dir``.

    Returns the failures and statistics (counts per outcome, seconds, worker restarts).
    Mutant ``i`` is ``mutant(seed[i % len(seeds)], fmt, start + i)``: deterministic.
    ``max_timeouts``: stop after that many timeouts or crashes (each costs the time limit
    and a worker restart; the target has failed already), noted as ``stats["stopped_after"]``.
    """
    fmt = TARGETS[target]
    work = save_dir / "_work" / target  # seeds' partner files stay beside the saved failures (replay)
    work.mkdir(parents=True, exist_ok=True)
    stats: dict = {"ok": 0, "repro_error": 0, "bad": 0, "n": 0}
    failures: list[Failure] = []
    slow: list = []
    t0 = time.monotonic()
    own = worker is None
    w = new_worker(work) if own else worker
    restarts0 = w.restarts
    try:
        sds = seeds(target, work, w)
        inputs = [(s, -1, s.data, FORMATS[fmt]["suffix"], "unmutated seed") for s in sds]
        specials = special_inputs(target, work, sds[0])
        stats["specials"] = len(specials)
        jobs = iter(range(n_mutants))
        for kind in ("seeds", "specials", "mutants"):
            for item in {"seeds": inputs, "specials": specials, "mutants": jobs}[kind]:
                if kind == "mutants":
                    i = item
                    s = sds[i % len(sds)]
                    data, suffix, desc = mutant(s.data, fmt, start + i)
                    item = (s, start + i, data, suffix, desc)
                    if time_budget is not None and time.monotonic() - t0 > time_budget:
                        stats["stopped_at_budget"] = i
                        break
                s, n, data, suffix, desc = item
                if kind == "specials":
                    p, data = data, b""
                else:
                    p = work / f"input{suffix}"
                    p.write_bytes(data)
                o = w.run(target, str(p), s.extra)
                stats["n"] += 1
                slow.append((round(o.seconds, 3), n, desc[:120]))
                slow.sort(reverse=True)
                del slow[3:]
                if not o.bad:
                    stats[o.outcome] += 1
                    if n == -1 and o.outcome != "ok":  # a seed must load
                        raise RuntimeError(f"seed {s.name} of {target} does not load: {o.type}: {o.message}")
                    continue
                stats["bad"] += 1
                d = save_dir / target
                d.mkdir(parents=True, exist_ok=True)
                for name in PARTNERS.get(target, ()):  # (a saved .gltf replays with its buffer beside it)
                    if not (d / name).exists():
                        (d / name).write_bytes((work / name).read_bytes())
                saved = d / f"{target}-n{n}{suffix}"
                saved.write_bytes(data)  # (empty for a special path: see the description)
                f = Failure(target, s.name, n, desc, o, saved, s.extra)
                saved.with_name(saved.name + ".txt").write_text(f.report() + "\n\n" + o.traceback + "\n", encoding="utf-8",
                                                                errors="backslashreplace")
                saved.with_name(saved.name + ".json").write_text(json.dumps(
                    {"target": target, "seed": s.name, "n": n, "mutation": desc, "extra": s.extra,
                     "suffix": suffix, "outcome": dataclasses.asdict(o)}, indent=1))
                failures.append(f)
                if progress:
                    progress(f)
                if max_timeouts is not None and o.outcome in ("timeout", "crash"):
                    stats["timeouts"] = stats.get("timeouts", 0) + 1
                    if stats["timeouts"] >= max_timeouts:
                        stats["stopped_after"] = n
                        break
            if "stopped_after" in stats:
                break
        stats["restarts"] = w.restarts - restarts0
    finally:
        if own:
            w.stop()
    stats["seconds"] = round(time.monotonic() - t0, 2)
    stats["slowest"] = slow
    stats["seeds"] = [s.name for s in sds]
    return failures, stats


# ------------------------------------------------------------------ minimising
def minimise(target: str, data: bytes, suffix: str, extra: dict, kind: str, *, worker: Worker, max_tries: int = 150) -> bytes:
    """A smaller input with the same failure signature (line, then token, then byte ddmin)."""
    work = Path(tempfile.mkdtemp(prefix="repro-fuzz-min-"))
    p = work / f"input{suffix}"
    tries = 0
    gz = suffix.endswith(".gz")
    if gz:
        try:
            data = gzip.decompress(data)
        except Exception:  # noqa: BLE001 - a corrupt stream: keep it as it is
            return data

    def same(candidate: bytes) -> bool:
        nonlocal tries
        tries += 1
        p.write_bytes(gzip.compress(candidate, mtime=0) if gz else candidate)
        o = w.run(target, str(p), extra)
        return o.bad and o.kind(target) == kind

    w = worker
    if True:
        if suffix in (".npz", ".glb"):  # binary containers: lines and tokens mean nothing
            return data
        for unit in ("line", "token", "byte"):
            if unit == "line":
                parts = data.split(b"\n")
                parts = [x + b"\n" for x in parts[:-1]] + [parts[-1]]
            elif unit == "token":
                parts = re.findall(rb"\s*\S+|\s+$", data) or [data]
            else:
                if len(data) > 400:
                    break
                parts = [data[i:i + 1] for i in range(len(data))]
            n = 2
            while len(parts) >= 2 and tries < max_tries:
                chunk = max(1, len(parts) // n)
                removed = False
                for i in range(0, len(parts), chunk):
                    cand = parts[:i] + parts[i + chunk:]
                    if cand and same(b"".join(cand)):
                        parts = cand
                        n = max(n - 1, 2)
                        removed = True
                        break
                    if tries >= max_tries:
                        break
                if not removed:
                    if chunk == 1:
                        break
                    n = min(len(parts), n * 2)
            data = b"".join(parts)
    return gzip.compress(data, mtime=0) if gz else data


def _saved_failures(raw: Path) -> list[Failure]:
    """Every failure saved under ``raw`` (``.json`` sidecars; ``.txt`` reports of older runs parsed)."""
    out = []
    for p in sorted(raw.glob("*/*")):
        js, txt = p.with_name(p.name + ".json"), p.with_name(p.name + ".txt")
        if not (js.is_file() or txt.is_file()):
            continue  # a sidecar itself
        if js.is_file():
            d = json.loads(js.read_text())
            out.append(Failure(d["target"], d["seed"], d["n"], d["mutation"], Outcome(**d["outcome"]), p,
                               d["extra"]))
        elif txt.is_file():
            t = txt.read_text(errors="replace")
            head, second = t.splitlines()[:2]
            m = re.match(r"\[(\w+)\] (\w+) in (.*?): ([\w.]+): (.*)", head)
            m2 = re.match(r"\s*seed '(.*?)', mutant n=(-?\d+): (.*)", second)
            if not m or not m2:
                continue
            extra = dict(re.findall(r" --(asf|amc) (\S+)", t.split("\n\n")[0]))
            tb = t.split("\n\n", 1)[1] if "\n\n" in t else ""
            out.append(Failure(m[1], m2[1], int(m2[2]), m2[3],
                               Outcome(m[2], m[4], m[5], tb, 0.0, "" if m[3] == "?" else m[3]), p, extra))
    return out


def _slug(kind: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.]+", "-", kind.replace(" | ", "--")).strip("-")[:120]


def summarise(out: Path, *, minimise_inputs: bool = True, targets=None) -> list[dict]:
    """One (minimised) input per failure kind of ``out/raw``, and ``out/signatures.json``.

    A kind is (target, stage, outcome, exception type); the distinct message heads of
    each kind are listed with their counts.
    """
    kinds: dict[str, list[Failure]] = {}
    for f in _saved_failures(out / "raw"):
        if targets is None or f.target in targets:
            kinds.setdefault(f.outcome.kind(f.target), []).append(f)
    rows = []
    w = new_worker(time_limit=TIME_LIMIT) if minimise_inputs else None
    for kind, fs in sorted(kinds.items()):
        f = min(fs, key=lambda f: (f.n <= -2, f.path.stat().st_size))
        data = f.path.read_bytes()
        suffix = "".join(f.path.suffixes[-2:]) if f.path.name.endswith(".gz") else f.path.suffix
        special = f.n <= -2
        if w is not None and not special and f.outcome.outcome != "timeout":
            try:
                data = minimise(f.target, data, suffix, f.extra, kind, worker=w)
            except Exception as exc:  # noqa: BLE001
                print("minimise failed:", exc)
        name = _slug(kind) + suffix
        (out / name).write_bytes(data)
        (out / (name + ".txt")).write_text(f.report() + "\n\n" + f.outcome.traceback + "\n", encoding="utf-8",
                                           errors="backslashreplace")
        heads: dict[str, int] = {}
        for g in fs:
            h = message_head(g.outcome.message)
            heads[h] = heads.get(h, 0) + 1
        rows.append({"file": name, "kind": kind, "count": len(fs), "seed": f.seed, "n": f.n,
                     "mutation": f.description, "stage": f.outcome.stage, "type": f.outcome.type,
                     "message": f.outcome.message[:500], "extra": f.extra,
                     "messages": dict(sorted(heads.items(), key=lambda kv: -kv[1]))})
        print(name, kind, len(fs), flush=True)
    if w is not None:
        w.stop()
    index = out / "signatures.json"
    if targets is not None and index.is_file():  # keep the other targets' rows
        rows = [r for r in json.loads(index.read_text()) if r["kind"].split(" | ")[0] not in targets] + rows
    rows.sort(key=lambda r: r["kind"])
    index.write_text(json.dumps(rows, indent=1, ensure_ascii=False))
    return rows


# ------------------------------------------------------------------ command line
def _main(argv=None) -> int:
    import argparse

    ap = argparse.ArgumentParser(prog="python -m tests.fuzz.harness")
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("run")
    r.add_argument("--n", type=int, default=1000, help="mutants per target")
    r.add_argument("--start", type=int, default=0, help="first mutant number")
    r.add_argument("--targets", nargs="*", default=list(TARGETS))
    r.add_argument("--out", required=True)
    r.add_argument("--no-minimise", action="store_true")
    r.add_argument("--raw-only", action="store_true", help="only save the failing inputs (summarise later)")
    sm = sub.add_parser("summarise", help="one minimised input per signature of OUT/raw, and signatures.json")
    sm.add_argument("--out", required=True)
    sm.add_argument("--no-minimise", action="store_true")
    sm.add_argument("--targets", nargs="*", default=None)
    rp = sub.add_parser("replay")
    rp.add_argument("target", choices=list(TARGETS))
    rp.add_argument("file")
    rp.add_argument("--asf")
    rp.add_argument("--amc")
    a = ap.parse_args(argv)
    if a.cmd == "replay":
        work = Path(tempfile.mkdtemp(prefix="repro-fuzz-replay-"))
        extra = {k: getattr(a, k) for k in ("asf", "amc") if getattr(a, k)}
        with new_worker(work) as w:
            o = w.run(a.target, a.file, extra)
        print(json.dumps(dataclasses.asdict(o), indent=1))
        return 1 if o.bad else 0
    out = Path(a.out)
    if a.cmd == "summarise":
        summarise(out, minimise_inputs=not a.no_minimise, targets=a.targets)
        return 0
    raw = out / "raw"
    all_stats = {}
    shared = new_worker()
    for t in a.targets:
        _, stats = run_target(t, a.n, raw, worker=shared, start=a.start,
                              progress=lambda f: print(f.report().splitlines()[0][:160], flush=True))
        all_stats[t] = stats
        print(t, stats, flush=True)
        (out / f"stats-{t}-{a.start}.json").write_text(json.dumps(stats, indent=1))
    shared.stop()
    if not a.raw_only:
        summarise(out, minimise_inputs=not a.no_minimise)
    return 0


if __name__ == "__main__":
    sys.exit(_main())
