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
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from repro.errors import UnknownFigureError

__all__ = ["Experiment", "Result", "experiment", "registry", "get", "run", "run_many", "input_key", "MANIFEST"]

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


def registry() -> dict[str, Experiment]:
    """All registered experiments, by name (importing the experiment modules)."""
    import repro.experiments  # noqa: F401  (registers)

    return dict(sorted(_REGISTRY.items()))


def get(name: str) -> Experiment:
    reg = registry()
    if name not in reg:
        raise UnknownFigureError(f"unknown figure or measurement {name!r}; known: {', '.join(reg) or 'none'}")
    return reg[name]


def run(name: str, outdir="figures", *, quick: bool = False) -> list[Path]:
    """Run experiment ``name`` and write its CSV (and PNG) into ``outdir``; the paths written."""
    from repro.io import save_figure, write_csv

    exp = get(name)
    result = exp.func(quick=quick)
    out = Path(outdir)
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
    import hashlib

    import repro

    root = Path(repro.__file__).parent
    h = hashlib.sha256()
    for f in sorted(root.rglob("*")):
        if f.suffix in (".py", ".csv") and "__pycache__" not in f.parts:
            h.update(str(f.relative_to(root)).encode())
            h.update(f.read_bytes())
    return h.hexdigest()


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
    """Everything a figure's outputs depend on: code, datasets present, mode, library versions."""
    return {
        "code_sha256": code or _code_fingerprint(),
        "data": {d: _dataset_fingerprint(d) for d in exp.data},
        "quick": bool(quick),
        "versions": _versions(),
    }


def _load_manifest(outdir: Path) -> dict:
    import json

    try:
        return json.loads((outdir / MANIFEST).read_text())
    except (OSError, ValueError):
        return {}


def _up_to_date(entry: dict | None, key: dict, outdir: Path) -> bool:
    if not entry or entry.get("inputs") != key:
        return False
    for f in entry.get("files", []):
        p = outdir / f["file"]
        if not p.is_file() or _sha256(p) != f["sha256"]:
            return False
    return True


def run_many(names, outdir="figures", *, quick: bool = False, force: bool = False, on_result=None) -> dict:
    """Run several figures, skipping those whose inputs and outputs are unchanged; update the manifest.

    The manifest (``outdir/manifest.json``) records for every figure: name,
    caption, producing function, notebooks that show it, the datasets used
    (with a sha256 over their registry entries), package versions, date, git
    commit, the files written with their sha256, and the input key used to
    decide whether a rerun is needed.  ``force`` reruns everything.  Returns
    ``{name: "ran" | "cached" | error message}``; ``on_result(name, status,
    paths)`` is called after each.
    """
    import datetime
    import json

    from repro.errors import ReproError
    from repro.io import write_text

    out = Path(outdir)
    manifest = _load_manifest(out)
    code = _code_fingerprint()
    status = {}
    for name in names:
        exp = get(name)
        key = input_key(exp, quick=quick, code=code)
        if not force and _up_to_date(manifest.get(name), key, out):
            status[name] = "cached"
            if on_result:
                on_result(name, "cached", [])
            continue
        try:
            paths = run(name, out, quick=quick)
        except ReproError as exc:
            status[name] = f"failed: {exc}"
            if on_result:
                on_result(name, status[name], [])
            continue
        manifest[name] = {
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
        write_text(out / MANIFEST, json.dumps(dict(sorted(manifest.items())), indent=1) + "\n")
        status[name] = "ran"
        if on_result:
            on_result(name, "ran", paths)
    return status
