"""Shared test set-up.

- Tests never touch the network: ``REPRO_OFFLINE=1``.
- The data folder defaults to the staged copy beside the checkout
  (``../shared/data``) when ``REPRO_DATA_DIR`` is not set.
- ``@pytest.mark.data("ict")`` skips a test with the data layer's own reason when
  that dataset is really absent; with ``REPRO_REQUIRE_DATA=1`` (CI) absence is an
  error instead, so CI cannot go green by skipping.
- A notebook declares what it needs in its metadata, ``"repro": {"needs_data":
  ["ict"], "needs_render": true}``, and gets the same markers (its stored
  outputs were made with that data, so without it nbval could only fail).
- ``@pytest.mark.render`` (and every notebook that uses pyvista) is probed once
  in a subprocess (VTK segfaults without an OpenGL, which would take pytest
  down); skipped with the reason, or an error with ``REPRO_REQUIRE_RENDER=1``.
- ``REPRO_NBVAL_COLD_BUSY=1`` (CI sets it): every notebook's kernel starts with
  cold caches (``HOME``, ``XDG_CACHE_HOME``, ``XDG_CONFIG_HOME``, ``MPLCONFIGDIR``,
  ``REPRO_CACHE_DIR`` and ``IPYTHONDIR`` in a fresh empty folder per notebook) on
  a busy machine (one CPU-bound child process per core while the notebooks run),
  so outputs that depend on speed, cache state or first use fail CI on every
  machine, not only on slow ones (issue 9).
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

os.environ["REPRO_OFFLINE"] = "1"
_staged = REPO.parent / "shared" / "data"
if not os.environ.get("REPRO_DATA_DIR") and _staged.is_dir():
    os.environ["REPRO_DATA_DIR"] = str(_staged)
os.environ.setdefault("MPLBACKEND", "Agg")

from hypothesis import settings  # noqa: E402

# shared 2-core machines are noisy: no per-example deadline, fixed derandomised runs
settings.register_profile("repro", deadline=None, derandomize=True, max_examples=60)
settings.load_profile("repro")


#: one folder per test session where its processes share the quick figures (repro.experiments.quick): the
#: run beside the tests computes them, notebook 00's kernel reads them (its caches stay cold: only this
#: run's results, verified, never a leftover of another run's)
_QUICK_SHARED = None


def pytest_configure(config):
    global _QUICK_SHARED
    from repro.experiments.quick import SHARED

    if not os.environ.get(SHARED):
        _QUICK_SHARED = tempfile.mkdtemp(prefix="repro-quick-")
        os.environ[SHARED] = _QUICK_SHARED
    if COLD_BUSY:
        config.pluginmanager.register(ColdBusyNotebooks(), "repro-cold-busy-notebooks")
    config.addinivalue_line("markers", "render: needs VTK off-screen rendering")
    config.addinivalue_line("markers", "data(name): needs staged dataset NAME")


def _notebook_needs(path: Path) -> dict:
    """A notebook's ``metadata.repro`` block: ``{"needs_data": [...], "needs_render": bool}``."""
    import json

    try:
        return json.loads(path.read_text()).get("metadata", {}).get("repro", {})
    except (OSError, ValueError):
        return {}


def pytest_collection_modifyitems(config, items):
    from repro import data

    for item in items:
        if item.path.suffix == ".ipynb":
            needs = _notebook_needs(item.path)
            if needs.get("needs_data"):
                item.add_marker(pytest.mark.data(*needs["needs_data"]))
            if needs.get("needs_render") or "pyvista" in item.path.read_text():
                item.add_marker(pytest.mark.render)

    if XDIST_WORKER:
        _order_for_workers(items)

    require_data = os.environ.get("REPRO_REQUIRE_DATA") == "1"
    for item in items:
        for mark in item.iter_markers("data"):
            for name in mark.args:
                reason = data.missing_reason(name)
                if reason is None:
                    continue
                if require_data:
                    raise pytest.UsageError(f"REPRO_REQUIRE_DATA=1 but {reason}")
                item.add_marker(pytest.mark.skip(reason=reason))

    if any(i.get_closest_marker("render") for i in items):
        from repro.ui.render import render_unavailable_reason

        reason = render_unavailable_reason()
        if reason:
            if os.environ.get("REPRO_REQUIRE_RENDER") == "1":
                raise pytest.UsageError(f"REPRO_REQUIRE_RENDER=1 but {reason}")
            for item in items:
                if item.get_closest_marker("render"):
                    item.add_marker(pytest.mark.skip(reason=reason))


# ------------------------------------------------------------------ two test processes (pytest-xdist)
#: set by pytest-xdist in its worker processes (scripts/test.sh runs ``-n auto --dist loadfile``: a worker takes a
#: file whole, so a module's fixtures are built once and a notebook's cells run in order in one kernel)
XDIST_WORKER = os.environ.get("PYTEST_XDIST_WORKER")
#: the files, or folders, whose tests take longest (measured with --durations): handed out first, so
#: that the two workers end together instead of one waiting on the other's last long file
FIRST = ("tests/test_cli.py", "tests/claims/", "tests/test_notebooks_embedded.py", "tests/experiments/test_legibility.py",
         "tests/fuzz/", "tests/browser/", "tests/bench/", "notebooks/")
#: handed out last: notebook 00 reads the quick figures the determinism test shares (tests/test_cli.py)
LAST = ("notebooks/00_overview.ipynb",)


#: the files whose tests read the session's quick figures (the ``quick_figures`` fixture): one worker takes them
#: all, so that the figures are computed once in the session (a test keeps this list in step with the fixture)
QUICK_FIGURE_FILES = ("tests/test_cli.py", "tests/claims/test_claims.py", "tests/claims/test_overview.py",
                      "tests/experiments/test_legibility.py", "tests/experiments/test_adaptation_figures.py",
                      "tests/experiments/test_feet_of_played_strikes.py", "tests/experiments/test_lewis_figures.py",
                      "tests/experiments/test_retrieval_figures.py", "tests/experiments/test_summaries.py",
                      "tests/test_progress_quiet.py")
#: the tests that each run a notebook on the embedded data (a long run each: one work unit each)
EMBEDDED_RUN = "tests/test_notebooks_embedded.py::test_notebook_runs_on_the_embedded_data_without_a_data_folder["


def work_unit(nodeid: str) -> str:
    """What one worker takes whole: a file (its module fixtures built once, a notebook's cells in order in one
    kernel); every file of :data:`QUICK_FIGURE_FILES` together; each notebook's run on the embedded data alone."""
    if nodeid.startswith(EMBEDDED_RUN):
        return nodeid
    path = nodeid.split("::", 1)[0]
    return "quick figures" if path in QUICK_FIGURE_FILES else path


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_make_scheduler(config, log):
    """Under ``-n``: the work units of :func:`work_unit`, handed out in the order the workers collected the tests
    (:func:`_order_for_workers`: the longest first), whatever ``--dist`` asked (every load mode would split a
    notebook's cells between kernels); ``--dist each`` and ``worksteal`` are refused for the same reason."""
    from xdist.scheduler import LoadScopeScheduling

    if config.getvalue("dist") not in ("load", "loadscope", "loadfile", "loadgroup"):
        raise pytest.UsageError(f"--dist {config.getvalue('dist')}: this suite runs with --dist loadfile "
                                "(a notebook's cells must run in order in one kernel)")

    class WorkUnits(LoadScopeScheduling):
        def __init__(self, config, log=None):
            super().__init__(config, log)
            config.option.loadscopereorder = False  # keep the order the tests were collected in

        def _split_scope(self, nodeid: str) -> str:
            return work_unit(nodeid)

    return WorkUnits(config, log)


def _order_for_workers(items) -> None:
    """The longest files first, notebook 00 last (``--dist loadfile`` hands files out in this order; a stable
    sort: the tests of a file, a notebook's cells, keep their order)."""
    def rank(item):
        where = item.path.relative_to(REPO).as_posix() if item.path.is_relative_to(REPO) else ""
        return 2 if where.startswith(LAST) else 0 if where.startswith(FIRST) else 1

    items[:] = sorted(items, key=rank)


# ------------------------------------------------------------------ notebooks cold and busy
COLD_BUSY = os.environ.get("REPRO_NBVAL_COLD_BUSY") == "1"
#: the variables pointed at an empty folder for each notebook's kernel (folder under the cold root)
COLD_VARS = {"HOME": "home", "XDG_CACHE_HOME": "cache", "XDG_CONFIG_HOME": "config", "MPLCONFIGDIR": "mpl",
             "REPRO_CACHE_DIR": "repro-cache", "IPYTHONDIR": "ipython"}
#: spins until its parent (pytest) is gone, so no burner outlives an interrupted run
_BURN = "import os, time\nppid = os.getppid()\nwhile os.getppid() == ppid:\n    t = time.time() + 0.5\n    while time.time() < t: pass\n"


def start_burners(n: int | None = None) -> list[subprocess.Popen]:
    """One CPU-bound child process per core (or ``n``), at normal priority."""
    return [subprocess.Popen([sys.executable, "-c", _BURN], stdin=subprocess.DEVNULL,
                             stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            for _ in range(n or os.cpu_count() or 1)]


def stop_burners(procs) -> None:
    for p in procs:
        p.kill()
    for p in procs:
        p.wait(timeout=30)


def cold_environment(root: Path) -> dict[str, str]:
    """The environment variables of a cold start, each pointing at a new empty folder under ``root``."""
    env = {}
    for var, sub in COLD_VARS.items():
        (root / sub).mkdir(parents=True)
        env[var] = str(root / sub)
    return env


class ColdBusyNotebooks:
    """Registered as a plugin (global: conftest hooks would only see items under tests/, not notebooks/).

    From a notebook's first cell to its last: its kernel's caches in a fresh folder, and CPU-bound
    processes running (one per core, or per core this process has under pytest-xdist, whose other
    workers keep the rest busy).  Other tests, before or after, run with neither.
    """

    def __init__(self):
        self.notebook = self.root = self.saved = None
        self.burners: list[subprocess.Popen] = []
        self.notebooks = 0

    def _leave(self) -> None:
        """The current notebook is done (its kernel is shut down by the next test's set-up)."""
        stop_burners(self.burners)
        self.burners = []
        if self.root is not None:
            shutil.rmtree(self.root, ignore_errors=True)
            self.root = None
        for var, value in (self.saved or {}).items():
            if value is None:
                os.environ.pop(var, None)
            else:
                os.environ[var] = value
        self.saved = self.notebook = None

    @pytest.hookimpl(tryfirst=True)
    def pytest_runtest_setup(self, item):
        """Before a notebook's kernel starts (nbval starts it when the notebook is set up)."""
        if item.path == self.notebook:
            return
        if self.notebook is not None:
            self._leave()
        if item.path.suffix != ".ipynb":
            return
        self.saved = {v: os.environ.get(v) for v in COLD_VARS}
        workers = int(os.environ.get("PYTEST_XDIST_WORKER_COUNT") or 1)
        self.burners = start_burners(max(1, (os.cpu_count() or 1) // workers))
        self.notebook = item.path
        self.root = Path(tempfile.mkdtemp(prefix="repro-cold-"))
        self.notebooks += 1
        os.environ.update(cold_environment(self.root))

    def pytest_sessionfinish(self, session, exitstatus):
        self._leave()

    def pytest_terminal_summary(self, terminalreporter):
        if self.notebooks:
            terminalreporter.write_line(
                f"REPRO_NBVAL_COLD_BUSY: {self.notebooks} notebook(s) ran with cold caches "
                f"({', '.join(COLD_VARS)} fresh per notebook) and every core kept busy meanwhile")


# ------------------------------------------------------------------ work beside the tests
#: REPRO_TEST_BESIDE=0 runs everything in the test that checks it (slower: nothing runs on the second core)
#: (under pytest-xdist the two workers are the two cores, and each test does its own work)
BESIDE_ON = os.environ.get("REPRO_TEST_BESIDE", "1") != "0" and not XDIST_WORKER
_BESIDE = None


def pytest_collection_finish(session):
    """Start the slow independent runs the selected tests check (tests/beside.py), beside the tests."""
    global _BESIDE
    from tests.beside import Beside

    _BESIDE = Beside()
    if not BESIDE_ON or session.config.option.collectonly:
        return
    for item in session.items:
        if item.get_closest_marker("skip"):
            continue
        name = getattr(item, "originalname", item.name)
        if name == "test_two_runs_give_identical_csvs_except_timing_columns" and not _BESIDE.has("figures"):
            _BESIDE.add_figures()
        elif name == "test_notebook_runs_on_the_embedded_data_without_a_data_folder":
            _BESIDE.add_notebook(item.callspec.params["path"])
    _BESIDE.start()


def pytest_unconfigure(config):
    if _BESIDE is not None:
        _BESIDE.stop()
    if _QUICK_SHARED is not None:
        shutil.rmtree(_QUICK_SHARED, ignore_errors=True)
        os.environ.pop("REPRO_QUICK_RESULTS", None)


@pytest.fixture(scope="session")
def beside():
    """The session's :class:`tests.beside.Beside` (jobs started at collection; ``has(key)`` says which)."""
    from tests.beside import Beside

    return _BESIDE if _BESIDE is not None else Beside()


# ------------------------------------------------------------------ shared computations
class QuickFigures:
    """Every registered figure computed at most once per test session, in quick mode.

    ``quick_figures(name)`` is the figure's :class:`~repro.experiments.registry.Result`; each
    call hands out copies of its tables, so no test can change what another reads.  The figure
    tests, the CLI tests, the claims test and the determinism test all read these.
    """

    def __init__(self):
        self._results: dict = {}

    def __call__(self, name: str):
        import dataclasses

        from repro.experiments import get
        from repro.experiments.registry import call_experiment

        if name not in self._results:
            self._results[name] = call_experiment(get(name), quick=True)
        r = self._results[name]
        return dataclasses.replace(r, table=_copy_table(r.table),
                                   extra_tables={k: _copy_table(t) for k, t in r.extra_tables.items()})

    def computed(self, name: str) -> bool:
        return name in self._results

    def serve(self, monkeypatch, *names: str) -> None:
        """Make the registry (``repro run``, :func:`repro.experiments.run`) answer ``names`` from here.

        For tests of the plumbing (files written, manifest, drawing), not of the numbers: the
        registered function is replaced by one of the same name that returns the shared result.
        """
        import dataclasses
        import functools
        import importlib

        registry = importlib.import_module("repro.experiments.registry")
        for name in names:
            self(name)  # computed before the registry answers from here
            exp = registry.get(name)

            @functools.wraps(exp.func)
            def served(quick=False, progress=False, _name=name, **kw):
                assert quick and not kw, "served figures are the quick ones with default arguments"
                return self(_name)

            monkeypatch.setitem(registry._REGISTRY, name, dataclasses.replace(exp, func=served))


def _copy_table(t):
    return t.copy(deep=True) if hasattr(t, "copy") else t


@pytest.fixture(scope="session")
def quick_figures() -> QuickFigures:
    return QuickFigures()


@pytest.fixture(scope="session")
def synthetic_dir(tmp_path_factory) -> Path:
    """The embedded motion database (75 BVH files and manifest.csv), written once per session.

    Tests must not change the folder (a test that writes takes its own copy).
    """
    from repro.motion.database.synthetic import synthetic_database

    d = tmp_path_factory.mktemp("synthetic")
    synthetic_database(d, seed=0)
    return d


@pytest.fixture(scope="session")
def _synthetic_db(synthetic_dir):
    from repro.motion.database.sources import build_database

    return build_database(synthetic_dir)


@pytest.fixture(scope="module")
def synthetic_db(_synthetic_db):
    """``build_database(synthetic_dir)``, built once per session; each module gets its own copy."""
    import copy

    return copy.deepcopy(_synthetic_db)
