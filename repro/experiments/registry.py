"""One registry for every figure and measurement: ``repro list / run / all``.

An experiment is a pure function of its inputs (and a seed) registered with
:func:`experiment`; it returns a :class:`Result` holding its numbers as a pandas
DataFrame and a small function that draws them.  :func:`run` writes
``NAME.csv`` first and then ``NAME.png``, both atomically, so the numbers exist
even where drawing fails (e.g. no OpenGL for a 3D panel: the figure then fails
with :class:`~repro.errors.RenderUnavailableError`, the CSV stays).
"""

from __future__ import annotations

import inspect
import os
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from repro.errors import UnknownFigureError

__all__ = ["Experiment", "Result", "experiment", "discover", "registry", "get", "run", "run_many", "input_key", "call_experiment",
           "output_folder", "MANIFEST"]

#: The manifest of every figure written into an output folder (see :func:`run_many`).
MANIFEST = "manifest.json"

#: Datasets each paper's figures use when present (a figure may declare its own).
_PAPER_DATA = {"lewis2005": ("ict",), "pronost2008": ("cmu-bvh",)}


@dataclass
class Result:
    """What an experiment returns: its numbers, and how to draw them."""

    table: "object"  # pandas.DataFrame
    draw: "Callable[[], object] | None" = None  # () -> matplotlib Figure
    extra_tables: dict = field(default_factory=dict)  # suffix -> DataFrame, written NAME-suffix.csv


@dataclass(frozen=True)
class Experiment:
    name: str
    caption: str
    func: Callable[..., Result]
    module: str
    paper: str  # "lewis2005" | "pronost2008"
    data: tuple = ()  #: datasets it uses when present
    timing: bool = False  #: its numbers include wall-clock measurements (differ run to run)

    @property
    def function(self) -> str:
        return f"{self.module}.{self.func.__name__}"


_REGISTRY: dict[str, Experiment] = {}


def experiment(name: str, caption: str, *, paper: str, data: tuple | None = None, timing: bool | None = None):
    """Register ``func(quick: bool = False) -> Result`` as figure/measurement ``name``.

    ``func`` may also take ``progress: bool = False`` (progress bars on stderr,
    passed only when asked for, as the CLI does; see :func:`call_experiment`).

    ``data``: datasets the figure uses when present (default: its paper's real
    data).  ``timing``: whether its table holds wall-clock measurements (default:
    guessed from the name: ``speed``, ``latency``, ``bench``).
    """

    def deco(func):
        if name in _REGISTRY:
            raise ValueError(f"experiment {name!r} registered twice")
        if "quick" not in inspect.signature(func).parameters:
            raise TypeError(f"experiment {name!r} must accept quick=")
        is_timing = any(w in name for w in ("speed", "latency", "bench")) if timing is None else bool(timing)
        _REGISTRY[name] = Experiment(name, caption, func, func.__module__, paper,
                                     tuple(_PAPER_DATA.get(paper, ()) if data is None else data), is_timing)
        return func

    return deco


def discover() -> None:
    """Import every figure module below this package (``lewis/``, ``pronost/``): each registers itself.

    Modules are found by walking the package folder and imported by name, so adding a figure
    is adding a module, and the registry imports no figure module statically (no import cycle).
    """
    import importlib
    import pkgutil

    package = __name__.rpartition(".")[0]
    for info in pkgutil.walk_packages([str(Path(__file__).parent)], prefix=package + "."):
        if not info.ispkg and not info.name.rpartition(".")[2].startswith("_") and info.name != __name__:
            importlib.import_module(info.name)


def registry() -> dict[str, Experiment]:
    """All registered experiments, by name (importing the experiment modules)."""
    discover()
    return dict(sorted(_REGISTRY.items()))


def get(name: str) -> Experiment:
    reg = registry()
    if name not in reg:
        raise UnknownFigureError(f"unknown figure or measurement {name!r}; known: {', '.join(reg) or 'none'}")
    return reg[name]


def call_experiment(exp: Experiment, *, quick: bool = False, progress: bool = False) -> Result:
    """``exp.func(quick=quick)``, with ``progress=progress`` when the function takes it.

    Progress bars are off unless asked for (the CLI asks): computing a figure from
    code or in a notebook prints nothing, however long a step takes.
    """
    if "progress" in inspect.signature(exp.func).parameters:
        return exp.func(quick=quick, progress=bool(progress))
    return exp.func(quick=quick)


def output_folder(outdir) -> Path:
    """``outdir`` as a Path, created if needed; a :class:`ReproError` when it cannot be a folder."""
    from repro.errors import ReproError

    out = Path(outdir)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except FileExistsError:
        raise ReproError(f"output folder {str(out)!r} exists and is a file, not a folder") from None
    except NotADirectoryError:
        raise ReproError(f"output folder {str(out)!r} cannot be made: part of its path is a file") from None
    except OSError as exc:
        raise ReproError(f"output folder {str(out)!r} cannot be made: {exc.strerror or exc}") from None
    if not out.is_dir():
        raise ReproError(f"output folder {str(out)!r} is not a folder")
    return out


def run(name: str, outdir="figures", *, quick: bool = False, progress: bool = False) -> list[Path]:
    """Run experiment ``name`` and write its CSV (and PNG) into ``outdir``; the paths written."""
    from repro.io import save_figure, write_csv

    exp = get(name)
    out = output_folder(outdir)
    result = call_experiment(exp, quick=quick, progress=progress)
    written = [write_csv(out / f"{name}.csv", result.table)]
    for suffix, table in result.extra_tables.items():
        written.append(write_csv(out / f"{name}-{suffix}.csv", table))
    if result.draw is not None:
        import matplotlib.pyplot as plt

        figure = result.draw()
        try:
            written.append(save_figure(out / f"{name}.png", figure))
        finally:
            plt.close(figure)
    return written


# ------------------------------------------------------------------ manifest and cache
def _sha256(path) -> str:
    import hashlib

    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def _code_fingerprint() -> str:
    """sha256 over every source file of the ``repro`` package (any code change invalidates)."""
    from repro.experiments.shared import source_fingerprint

    return source_fingerprint()


def _dataset_fingerprint(name: str) -> str | None:
    """sha256 of a dataset's registry entries when all its files are present, else None."""
    import hashlib

    from repro import data

    if data.missing_reason(name) is not None:
        return None
    h = hashlib.sha256()
    for f in sorted(data.files(name), key=lambda f: f.path):
        h.update(f"{f.path} {f.sha256}\n".encode())
    return h.hexdigest()


def _versions() -> dict:
    import platform
    from importlib.metadata import PackageNotFoundError, version

    out = {"python": platform.python_version()}
    for pkg in ("repro", "numpy", "scipy", "pandas", "matplotlib", "pyvista", "vtk"):
        try:
            out[pkg] = version(pkg)
        except PackageNotFoundError:
            out[pkg] = None
    return out


def _git_commit() -> str | None:
    import subprocess

    try:
        p = subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True, timeout=10,
                           cwd=Path(__file__).resolve().parents[2])
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], capture_output=True,
                               text=True, timeout=10, cwd=Path(__file__).resolve().parents[2])
    except (OSError, subprocess.SubprocessError):
        return None
    if p.returncode:
        return None
    return p.stdout.strip() + ("+dirty" if dirty.stdout.strip() else "")


def _notebooks_using(name: str) -> list[str]:
    """Notebooks whose code cells name this figure as a string literal (e.g. ``get("fig5_alpha")``)."""
    import json
    import re

    root = Path(__file__).resolve().parents[2] / "notebooks"
    if not root.is_dir():
        return []
    pattern = re.compile(rf"[\"']{re.escape(name)}[\"']")
    found = []
    for nb in sorted(root.glob("*.ipynb")):
        try:
            cells = json.loads(nb.read_text()).get("cells", [])
        except (OSError, ValueError):
            continue
        code = "\n".join("".join(c.get("source", "")) for c in cells if c.get("cell_type") == "code")
        if pattern.search(code):
            found.append(f"notebooks/{nb.name}")
    return found


def input_key(exp: Experiment, *, quick: bool, code: str | None = None) -> dict:
    """Everything a figure's outputs depend on: code, datasets present, mode, library versions,
    and the user's faces in use (``faces``, by content hash; only when there are any)."""
    key = {
        "code_sha256": code or _code_fingerprint(),
        "data": {d: _dataset_fingerprint(d) for d in exp.data},
        "quick": bool(quick),
        "versions": _versions(),
    }
    if exp.paper.startswith("lewis"):
        from repro.experiments.lewis import common

        if faces := common.face_inputs():
            key["faces"] = faces
    return key


def _read_manifest(outdir: Path) -> tuple[dict, str | None]:
    """The manifest's valid entries, and what is wrong with the file (None when nothing is).

    A valid entry is a JSON object under its figure's name.  A file that is not
    JSON, or whose top level is not an object (``[]``, ``null``), has no valid
    entry; entries that are not objects (``{"fig4...": 3}``) are left out.
    """
    import json

    path = outdir / MANIFEST
    try:
        text = path.read_bytes().decode("utf-8")
    except FileNotFoundError:
        return {}, None
    except (OSError, UnicodeDecodeError) as exc:
        return {}, f"cannot be read ({exc})"
    try:
        doc = json.loads(text)
    except ValueError as exc:
        return {}, f"is not valid JSON ({exc})"
    except RecursionError:  # json's decoder recurses per nesting level: a 2,000-deep list
        return {}, "nests JSON deeper than Python's recursion limit"
    if not isinstance(doc, dict):
        return {}, f"holds a JSON {type(doc).__name__ if doc is not None else 'null'}, not an object of figures"
    valid = {k: v for k, v in doc.items() if isinstance(v, dict)}
    bad = sorted(set(doc) - set(valid))
    if bad:
        return valid, f"has entries that are not objects: {', '.join(map(repr, bad[:5]))}{' ...' if len(bad) > 5 else ''}"
    return valid, None


def _load_manifest(outdir: Path) -> dict:
    return _read_manifest(outdir)[0]


def _update_manifest(outdir: Path, name: str, entry: dict) -> None:
    """Merge ``entry`` into the manifest under a lock (read, merge, atomic write).

    Several ``repro run`` processes writing into one folder each add their own
    entries, none lost.  A damaged manifest is kept as ``manifest.json.damaged``
    and rebuilt from its valid entries, with a :class:`~repro.errors.ReproWarning`.
    """
    import json
    import warnings

    from repro.errors import ReproWarning
    from repro.io import file_lock, write_text

    path = outdir / MANIFEST
    with file_lock(_manifest_lock(outdir)):
        manifest, damage = _read_manifest(outdir)
        if damage is not None:
            backup = path.with_name(MANIFEST + ".damaged")
            try:
                os.replace(path, backup)
                kept = f"moved to {backup}"
            except OSError as exc:
                kept = f"could not be moved aside ({exc})"
            warnings.warn(f"{path} {damage}; the damaged file was {kept} and the manifest rebuilt "
                          f"with its {len(manifest)} valid entr{'y' if len(manifest) == 1 else 'ies'}",
                          ReproWarning, stacklevel=3)
        manifest[name] = entry
        write_text(path, json.dumps(dict(sorted(manifest.items())), indent=1) + "\n")


def _manifest_lock(outdir: Path) -> Path:
    """Where the manifest's lock file lives: the temp folder, one per user and output folder.

    (Not in the output folder, which holds only what the figures wrote and the manifest.)
    """
    from repro.io import lock_path

    return lock_path("manifest", outdir)


def _up_to_date(entry: dict | None, key: dict, outdir: Path) -> bool:
    if not isinstance(entry, dict) or entry.get("inputs") != key:
        return False
    try:
        for f in entry.get("files", []):
            p = outdir / f["file"]
            if not p.is_file() or _sha256(p) != f["sha256"]:
                return False
    except (TypeError, KeyError, AttributeError, OSError):  # a hand-edited entry: rerun
        return False
    return True


def run_many(names, outdir="figures", *, quick: bool = False, force: bool = False, on_result=None,
             progress: bool = False, faces=(), jobs: int = 1) -> dict:
    """Run several figures, skipping those whose inputs and outputs are unchanged; update the manifest.

    The manifest (``outdir/manifest.json``) records for every figure: name,
    caption, producing function, notebooks that show it, the datasets used
    (with a sha256 over their registry entries), package versions, date, git
    commit, the files written with their sha256, and the input key used to
    decide whether a rerun is needed.  ``force`` reruns everything.  Returns
    ``{name: "ran" | "cached" | error message}``; ``on_result(name, status,
    paths)`` is called after each.  Each entry is merged into the manifest under
    a lock, so concurrent runs into one folder keep each other's entries; a
    damaged manifest is rebuilt from its valid entries, with a warning.
    ``progress``: progress bars (stderr) for figures that have them.  The augmented databases
    the figures build are kept on disk for the next run (:mod:`repro.experiments.shared`).  ``faces``: glTF
    faces added to every Lewis figure (all read first; a bad one is a ModelError
    before any figure runs), part of the input key by content hash.

    ``jobs`` > 1: the figures without wall-clock numbers are computed in that many worker
    processes (``spawn``ed: no fork after threads), each writing its own CSV/PNG atomically;
    this process alone checks, hashes and merges them into the manifest.  The timing figures
    then run here, one by one, after the workers have stopped, so nothing else runs while
    they measure.  A worker that dies (killed, out of memory) fails its figure, and the
    temporary files it left in ``outdir`` are removed.  The workers die with this process,
    whatever ends it (SIGKILL included), and publish nothing once it is gone; the temporary
    files a killed run left of these figures are removed before they run (issue 23, section 1).
    """
    from repro.experiments import shared
    from repro.experiments.lewis import common

    out = output_folder(outdir)
    with common.use_faces(faces), shared.kept_on_disk():  # the databases figures share, kept for the next run
        return _run_many(names, out, quick=quick, force=force, on_result=on_result, progress=progress,
                         faces=faces, jobs=jobs)


def _run_many(names, out, *, quick, force, on_result, progress, faces=(), jobs=1) -> dict:
    from repro.errors import ReproError

    if isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1:
        raise ReproError(f"jobs must be a whole number >= 1, got {jobs!r}")
    for name in names:
        get(name)  # (unknown names refused before anything is touched)
    from repro.io import file_lock

    with file_lock(_manifest_lock(out)):  # what a killed run left of these figures (and of the manifest)
        for name in [*names, MANIFEST]:
            _remove_temporaries(out, name)
    manifest = _load_manifest(out)
    code = _code_fingerprint()
    status = {}
    keys = {}
    todo = []
    for name in names:
        exp = get(name)
        keys[name] = input_key(exp, quick=quick, code=code)
        if not force and _up_to_date(manifest.get(name), keys[name], out):
            status[name] = "cached"
            if on_result:
                on_result(name, "cached", [])
        else:
            todo.append(name)

    def done(name, result):
        if isinstance(result, str):  # "failed: ..."
            status[name] = result
            if on_result:
                on_result(name, result, [])
            return
        manifest[name] = _record(out, get(name), keys[name], result)
        status[name] = "ran"
        if on_result:
            on_result(name, "ran", result)

    pooled = [n for n in todo if not get(n).timing] if jobs > 1 else []
    if len(pooled) > 1:
        _run_pool(pooled, out, quick=quick, progress=progress, faces=faces, jobs=jobs, done=done)
    else:
        pooled = []
    for name in todo:  # everything with jobs=1; else the timing figures, alone, after the workers stopped
        if name in pooled:
            continue
        try:
            paths = run(name, out, quick=quick, progress=progress)
        except ReproError as exc:
            done(name, f"failed: {exc}")
            continue
        done(name, paths)
    return {n: status[n] for n in names}


# ------------------------------------------------------------------ worker processes (``jobs`` > 1)
_WORKER: list = []


def _worker_start(faces, modules, parent: int | None = None) -> None:
    """A worker's set-up: the user's faces and the on-disk database cache, for its whole life;
    it dies with ``parent`` (the process running the pool) and publishes nothing after it."""
    import contextlib
    import importlib

    from repro.experiments import shared
    from repro.experiments.lewis import common

    if parent is not None:
        _die_with_parent(parent)
    for module in modules:  # figures registered outside this package (e.g. by tests)
        importlib.import_module(module)
    stack = contextlib.ExitStack()
    stack.enter_context(common.use_faces(faces))
    stack.enter_context(shared.kept_on_disk())
    _WORKER.append(stack)  # kept open until the process ends


def _die_with_parent(parent: int) -> None:
    """End this process when ``parent`` ends, however it ends (SIGKILL included), and never publish
    a file (:data:`repro.io.publish_hooks`) once it has: a killed ``repro run`` leaves nothing behind.

    On Linux the kernel sends SIGKILL when the parent dies (:func:`repro.processes.die_with_parent`; it
    fires when the parent's *thread* that started this process ends: :func:`_pool` starts its workers
    from the thread that waits for them).  Elsewhere, or should prctl fail, a thread polls the parent.
    (The resource tracker ``spawn`` starts beside the workers ends by itself once every process
    holding its pipe, the parent and these workers, has ended.)
    """
    import threading

    from repro import io, processes

    processes.die_with_parent(parent)
    io.publish_hooks.append(lambda tmp, path: _publish_guard(parent, tmp))
    threading.Thread(target=_watch_parent, args=(parent,), name="repro-watch-parent", daemon=True).start()


def _orphaned(parent: int) -> bool:
    return os.getppid() != parent  # (an orphan is adopted by init or a subreaper)


def _watch_parent(parent: int, every: float = 0.25) -> None:
    """The portable fallback of the parent-death signal: end this process once ``parent`` is gone."""
    import time

    while not _orphaned(parent):
        time.sleep(every)
    os._exit(1)


def _publish_guard(parent: int, tmp) -> None:
    """Before a file is moved into place: if the run's process is gone, remove it and end here."""
    if _orphaned(parent):
        import contextlib

        with contextlib.suppress(OSError):
            os.unlink(tmp)
        os._exit(1)


def _worker_run(name: str, outdir: str, quick: bool, progress: bool):
    """:func:`run` in a worker: the paths written (as strings), or ``"failed: ..."`` for a ReproError."""
    from repro.errors import ReproError

    try:
        return [str(p) for p in run(name, outdir, quick=quick, progress=progress)]
    except ReproError as exc:  # a message, not the exception: a custom exception need not pickle
        return f"failed: {exc}"


def _run_pool(names, out: Path, *, quick, progress, faces, jobs, done) -> None:
    """Compute ``names`` in ``jobs`` spawned processes; ``done(name, paths | "failed: ...")`` here, as each ends.

    A dying worker breaks the whole pool: the figures it took down with it are computed
    again, each in a process of its own, so only the one that kills its process fails.
    """
    broken = _pool(names, out, quick=quick, progress=progress, faces=faces, jobs=jobs, done=done)
    for name in broken:
        if _pool([name], out, quick=quick, progress=progress, faces=faces, jobs=1, done=done):
            done(name, "failed: its worker process died (killed, out of memory, or crashed)")


def _pool(names, out: Path, *, quick, progress, faces, jobs, done) -> list:
    """One pool over ``names``; the names whose worker died (not passed to ``done``)."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor, as_completed
    from concurrent.futures.process import BrokenProcessPool

    package = __name__.rpartition(".")[0] + "."
    modules = sorted({get(n).module for n in names if not get(n).module.startswith(package)})
    pool = ProcessPoolExecutor(max_workers=min(jobs, len(names)), mp_context=multiprocessing.get_context("spawn"),
                               initializer=_worker_start,
                               initargs=(tuple(str(f) for f in faces), tuple(modules), os.getpid()))
    pending, broken = {}, []
    try:
        # (submit starts the workers, from this thread, which outlives them: their parent-death signal
        # is tied to it; see _die_with_parent)
        pending = {pool.submit(_worker_run, n, str(out), quick, progress): n for n in names}
        for fut in as_completed(list(pending)):
            name = pending.pop(fut)
            try:
                result = fut.result()
            except BrokenProcessPool:
                broken.append(name)
                continue
            done(name, result if isinstance(result, str) else [Path(p) for p in result])
    except BaseException:  # Ctrl-C, or an error that is not repro's: stop the workers now, not after their figures
        # (ProcessPoolExecutor.terminate_workers is Python >= 3.14; before, its process table is the only handle)
        for proc in list((getattr(pool, "_processes", None) or {}).values()):
            proc.terminate()
        raise
    finally:
        pool.shutdown(wait=True, cancel_futures=True)
        # unfinished or broken: what their workers were writing when stopped (only now that the workers
        # have ended: a broken pool fails its futures before it terminates the other workers)
        for name in [*broken, *pending.values()]:
            _remove_temporaries(out, name)
    return [n for n in names if n in broken]


def _remove_temporaries(out: Path, name: str) -> None:
    """The temporary files (:func:`repro.io.atomic_path`) of figure ``name`` whose writer is gone (a dead
    worker, a killed run); those another run is writing now are kept."""
    import glob

    from repro.io import remove_stale_temporary

    stem = glob.escape(name)
    for tmp in sorted({*out.glob(f".{stem}.*.tmp"), *out.glob(f".{stem}-*.tmp")}):
        remove_stale_temporary(tmp)


def _record(out: Path, exp: Experiment, key: dict, paths) -> dict:
    """The manifest entry of a figure just written (merged into the manifest under its lock)."""
    import datetime

    name = exp.name
    entry = {
        "name": name,
        "caption": exp.caption,
        "paper": exp.paper,
        "function": exp.function,
        "notebooks": _notebooks_using(name),
        "data": {d: key["data"][d] for d in exp.data},
        "timing": exp.timing,
        "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "git_commit": _git_commit(),
        "inputs": key,
        "files": [{"file": p.name, "sha256": _sha256(p)} for p in paths],
    }
    _update_manifest(out, name, entry)
    return entry
