"""Work the test session runs beside the tests, in child processes, one at a time (the second core).

The slowest checks of the suite wait on child processes anyway (a notebook's kernel) or
need a second, independent run (the determinism test): they are started in the background
when the session's tests are collected (:class:`Beside`, registered by ``tests/conftest.py``)
and the test that checks them waits for their result.  The checks themselves are the
tests' own; only where the work runs changes.

    python -m tests.beside notebook NOTEBOOK OUT.ipynb   run a notebook with DATA = "embedded"
    python -m tests.beside figures OUT.json              every quick figure, as CSV text (and shared: _figures)
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import threading
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]

#: columns holding wall-clock measurements, or flags and labels derived from them (the determinism test's)
TIMING_COLUMN = r"(_ms|_us|_s|speedup|ratio|_over_|meets_goal|within_budget|machine|bench)"


def csv_tables(result, timing: bool) -> dict:
    """``{suffix: {"columns": [...], "csv": text}}`` of a figure's tables; timing figures without their timing columns."""
    import re

    from repro.io import csv_text

    out = {}
    for suffix, t in [("", result.table), *result.extra_tables.items()]:
        keep = [c for c in t.columns if not (timing and re.search(TIMING_COLUMN, c))]
        out[suffix] = {"columns": [str(c) for c in t.columns], "csv": csv_text(t[keep])}
    return out


def fresh_figures() -> dict:
    """Every quick figure computed again, as :func:`csv_tables`; shared with the run's notebook kernels.

    The results and their pictures go into the run's shared folder too (:mod:`repro.experiments.quick`,
    set up by tests/conftest.py), where notebook 00's kernel under nbval reads them instead of computing
    every figure a third time.  The session's own results (``quick_figures``) are never read from there:
    the determinism test compares two runs that share nothing.
    """
    from repro.experiments import quick, registry
    from repro.experiments.registry import call_experiment

    tables = {}
    for name, exp in registry().items():
        result = call_experiment(exp, quick=True)
        tables[name] = csv_tables(result, exp.timing)
        quick.share(name, result)
    return tables


def _figures(out: Path) -> None:
    """:func:`fresh_figures`, as JSON into ``out`` (run in a process of its own beside the tests)."""
    from repro.io import write_text

    write_text(out, json.dumps(fresh_figures()))


def fresh_figures_in_a_process() -> dict:
    """:func:`fresh_figures` in a new process (nothing in memory shared with this one), waited for."""
    import functools

    from repro.processes import die_with_parent

    with tempfile.TemporaryDirectory(prefix="repro-figures-") as tmp:
        out = Path(tmp) / "figures.json"
        run = subprocess.run([sys.executable, "-m", "tests.beside", "figures", str(out)], cwd=REPO,
                             stdin=subprocess.DEVNULL, capture_output=True, text=True,
                             preexec_fn=functools.partial(die_with_parent, os.getpid()))  # ends with this test process
        if run.returncode != 0:
            raise RuntimeError(f"the second run of the quick figures failed:\n{run.stdout[-10000:]}{run.stderr[-10000:]}")
        return json.loads(out.read_text())


def _notebook(path: Path, out: Path) -> int:
    import nbformat
    from nbclient.exceptions import CellExecutionError

    from tests.test_notebooks_embedded import _execute, _with_parameter

    nb = _with_parameter(nbformat.read(path, as_version=4), "embedded")
    try:
        done = _execute(nb)
    except CellExecutionError as exc:
        out.with_suffix(".error").write_text(str(exc))
        return 1
    nbformat.write(done, str(out))
    return 0


class Beside:
    """Child processes run one after the other in a background thread; :meth:`wait` gives one's result."""

    def __init__(self):
        self.root = Path(tempfile.mkdtemp(prefix="repro-beside-"))
        self.jobs: dict[str, tuple[list[str], dict, threading.Event]] = {}
        self.order: list[str] = []
        self.results: dict[str, tuple[int, str]] = {}
        self.current: subprocess.Popen | None = None
        self.stopped = False
        self.thread: threading.Thread | None = None

    def add(self, key: str, argv: list[str], env: dict | None = None) -> None:
        self.jobs[key] = (argv, {**os.environ, **(env or {})}, threading.Event())
        self.order.append(key)

    def start(self) -> None:
        if self.order and self.thread is None:
            self.thread = threading.Thread(target=self._run, name="repro-beside", daemon=True)
            self.thread.start()

    def _run(self) -> None:
        for key in self.order:
            argv, env, done = self.jobs[key]
            if self.stopped:
                self.results[key] = (-1, "the session ended first")
            else:
                log = self.root / f"{key.replace('/', '_')}.log"
                with open(log, "wb") as fh:
                    self.current = subprocess.Popen(argv, env=env, cwd=REPO, stdin=subprocess.DEVNULL, stdout=fh,
                                                    stderr=subprocess.STDOUT, start_new_session=True)
                    rc = self.current.wait()
                self.results[key] = (rc, log.read_text(errors="replace")[-20000:])
            done.set()

    # ------------------------------------------------------------ the two kinds of job
    def add_notebook(self, path: Path) -> None:
        """``path`` run as a fresh clone would (as ``fresh_clone`` in tests/test_notebooks_embedded.py sets up)."""
        base = self.root / f"notebook-{path.stem}"
        (base / "no-data").mkdir(parents=True)
        env = {"REPRO_DATA_DIR": str(base / "no-data"), "REPRO_OFFLINE": "1", "REPRO_CACHE_DIR": str(base / "cache"),
               "MPLCONFIGDIR": str(base / "mpl"), "MPLBACKEND": "Agg",
               "PYTHONPATH": os.pathsep.join([str(REPO)] + [p for p in [os.environ.get("PYTHONPATH")] if p])}
        self.add(f"notebook-{path.stem}", [sys.executable, "-m", "tests.beside", "notebook", str(path),
                                           str(base / "done.ipynb")], env)

    def notebook(self, path: Path):
        """(the executed notebook, its data folder) of :meth:`add_notebook`; a failed cell fails the test, named."""
        import nbformat
        import pytest

        rc, log = self.wait(f"notebook-{path.stem}")
        base = self.root / f"notebook-{path.stem}"
        if rc != 0:
            err = base / "done.error"
            pytest.fail(f"{path.name} did not run on the embedded data:\n"
                        + (err.read_text() if err.exists() else log), pytrace=False)
        return nbformat.read(base / "done.ipynb", as_version=4), base / "no-data"

    def add_figures(self) -> None:
        self.add("figures", [sys.executable, "-m", "tests.beside", "figures", str(self.root / "figures.json")])

    def figures(self) -> dict:
        """:func:`csv_tables` of every quick figure, computed in a process of its own."""
        rc, log = self.wait("figures")
        if rc != 0:
            raise RuntimeError(f"the second run of the quick figures failed:\n{log}")
        return json.loads((self.root / "figures.json").read_text())

    def has(self, key: str) -> bool:
        return key in self.jobs

    def wait(self, key: str, timeout: float = 3600) -> tuple[int, str]:
        """(exit status, the tail of its output) of job ``key``, once it has run."""
        if not self.jobs[key][2].wait(timeout):
            raise TimeoutError(f"background job {key} did not finish in {timeout:.0f} s")
        return self.results[key]

    def stop(self) -> None:
        self.stopped = True
        if self.current is not None and self.current.poll() is None:
            import signal

            try:
                os.killpg(self.current.pid, signal.SIGKILL)  # with the notebook's kernel
            except OSError:
                pass
            self.current.wait(timeout=30)
        import shutil

        shutil.rmtree(self.root, ignore_errors=True)


if __name__ == "__main__":
    what = sys.argv[1]
    if what == "figures":
        _figures(Path(sys.argv[2]))
        sys.exit(0)
    if what == "notebook":
        sys.exit(_notebook(Path(sys.argv[2]), Path(sys.argv[3])))
    sys.exit(f"unknown job {what!r}")
