"""A killed ``repro run --jobs`` leaves nothing behind (issue 23, sections 1 and 8).

Its workers die with their parent, whatever kills it (SIGKILL included), publish nothing once it
is gone, and the next run removes the temporary files the killed one left (those of its figures
only, and only those no process is writing).
"""

from __future__ import annotations

import contextlib
import importlib
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from repro import io
from repro.experiments.registry import run_many

registry_mod = importlib.import_module("repro.experiments.registry")  # (``repro.experiments.registry`` is the function)
ROOT = Path(__file__).resolve().parents[1]

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="walks /proc")


@pytest.fixture
def jobs_figures():
    module = importlib.import_module("tests.jobs_figures")
    yield module
    module.unregister()


def _session(sid: int) -> dict:
    """The live processes of session ``sid`` (``start_new_session``), ``{pid: command line}``; zombies are dead."""
    found = {}
    for proc in Path("/proc").iterdir():
        if not proc.name.isdigit():
            continue
        try:
            stat = (proc / "stat").read_text()
            cmd = (proc / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace").strip()
        except OSError:  # (ended meanwhile)
            continue
        fields = stat[stat.rindex(")") + 2:].split()  # state ppid pgrp session ...
        if int(fields[3]) == sid and fields[0] not in "ZX":
            found[int(proc.name)] = cmd
    return found


def _listing(folder: Path) -> dict:
    """Every entry of ``folder`` (hidden ones too), with its size and modification time."""
    return {p.name: (p.stat().st_size, p.stat().st_mtime_ns) for p in folder.iterdir()}


_RUN = """
import sys
import tests.jobs_figures
from repro.cli import main
sys.exit(main(["run", "zz_jobs_orphan_a", "zz_jobs_orphan_b", "zz_jobs_a", "--jobs", "2", "--out", sys.argv[1]]))
"""


def test_sigkill_of_the_parent_ends_every_process_of_the_run_and_nothing_is_written_after_it(tmp_path):
    """SIGKILL the parent of ``repro run ... --jobs 2`` while both workers compute (one with its CSV
    half-written): 5 s later no process of the run is alive (workers, resource tracker) and nothing in
    the output folder changed; the next run into it succeeds and leaves no temporary file."""
    out = tmp_path / "out"
    out.mkdir()
    env = dict(os.environ, ZZ_JOBS_ORPHAN_IN=str(tmp_path), ZZ_JOBS_ORPHAN_OUT=str(out),
               REPRO_CACHE_DIR=str(tmp_path / "cache"))
    p = subprocess.Popen([sys.executable, "-c", _RUN, str(out)], cwd=ROOT, env=env, start_new_session=True,
                         stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 180
        while len(list(tmp_path.glob("started-*"))) < 2:  # both workers inside their figures
            assert time.monotonic() < deadline and p.poll() is None, p.communicate()
            time.sleep(0.05)
        workers = {int(m.name.split("-")[1]) for m in tmp_path.glob("started-*")}
        assert workers <= set(_session(p.pid)) and len(_session(p.pid)) >= 3  # parent, workers (and tracker)
        assert len(list(out.glob(".zz_jobs_orphan_a.csv.*.tmp"))) == 1  # half-written

        os.kill(p.pid, signal.SIGKILL)  # the parent only
        p.wait()
        at_kill = _listing(out)
        for _ in range(100):  # 5 s for the kernel to end them
            if not _session(p.pid):
                break
            time.sleep(0.05)
        assert _session(p.pid) == {}, "processes of the killed run still alive"
        assert _listing(out) == at_kill, "written after the parent was killed"
        assert sorted(at_kill) == [next(iter(out.glob(".zz_jobs_orphan_a.csv.*.tmp"))).name]
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(p.pid, signal.SIGKILL)
        p.wait()

    # the next run (its figures quick now) into the same folder: no temporary file stays
    env = {k: v for k, v in env.items() if not k.startswith("ZZ_JOBS_ORPHAN")}
    q = subprocess.run([sys.executable, "-c", _RUN, str(out)], cwd=ROOT, env=env, capture_output=True, text=True,
                       timeout=600, start_new_session=True)
    assert q.returncode == 0, q.stderr
    assert sorted(x.name for x in out.iterdir()) == [
        "manifest.json", "zz_jobs_a-more.csv", "zz_jobs_a.csv", "zz_jobs_orphan_a.csv", "zz_jobs_orphan_b.csv"]


def test_the_next_run_removes_the_stale_temporaries_of_its_figures_only(jobs_figures, tmp_path, monkeypatch):
    """A killed run's ``.NAME.XXXX.tmp`` files (0 bytes, as a group kill leaves them) are removed by the
    next run of those figures; another figure's, and one another run is writing now, are kept."""
    monkeypatch.setattr(registry_mod, "_code_fingerprint", lambda: "fixed")  # (cached below, whatever is edited)
    out = tmp_path
    stale = [".zz_jobs_a.csv.abc123.tmp", ".zz_jobs_a.png.k2j4l0.tmp", ".zz_jobs_a-more.csv.x1.tmp",
             ".zz_jobs_b.csv.q9.tmp", ".manifest.json.zz01.tmp"]
    kept = [".zz_jobs_ab.csv.r7.tmp", ".fig4_axis_selection.png.m3.tmp", ".zz_jobs_b.csv.writing.tmp"]
    for name in stale + kept:
        (out / name).write_bytes(b"")
    live = os.open(out / ".zz_jobs_b.csv.writing.tmp", os.O_RDONLY)  # as a concurrent writer holds it
    try:
        import fcntl

        fcntl.flock(live, fcntl.LOCK_EX)
        assert set(run_many(["zz_jobs_a", "zz_jobs_b"], out, jobs=1).values()) == {"ran"}
    finally:
        os.close(live)
    assert sorted(p.name for p in out.glob(".*")) == sorted(kept)
    # and a cached rerun too (its figures do not run, their temporaries still go)
    (out / ".zz_jobs_a.csv.abc123.tmp").write_bytes(b"")
    assert set(run_many(["zz_jobs_a", "zz_jobs_b"], out, jobs=1).values()) == {"cached"}
    assert sorted(p.name for p in out.glob(".*")) == sorted(kept[:2])


def test_atomic_path_holds_its_temporary_against_the_stale_remover(tmp_path):
    target = tmp_path / "x.csv"
    with io.atomic_path(target) as tmp:
        tmp.write_text("x\n")
        assert not io.remove_stale_temporary(tmp) and tmp.exists()  # being written: kept
    assert target.read_text() == "x\n" and not tmp.exists()
    left = tmp_path / ".x.csv.dead00.tmp"
    left.write_text("half")
    assert io.remove_stale_temporary(left) and not left.exists()
    (tmp_path / "elsewhere").write_text("keep")
    (tmp_path / ".x.csv.link00.tmp").symlink_to(tmp_path / "elsewhere")
    assert not io.remove_stale_temporary(tmp_path / ".x.csv.link00.tmp")  # not a file of atomic_path's
    assert (tmp_path / "elsewhere").read_text() == "keep"
    os.mkfifo(tmp_path / ".x.csv.fifo00.tmp")
    assert not io.remove_stale_temporary(tmp_path / ".x.csv.fifo00.tmp")  # nor a FIFO (and no hang)
    assert (tmp_path / ".x.csv.fifo00.tmp").exists()


_GUARDED = """
import importlib, sys
from pathlib import Path
from repro import io
reg = importlib.import_module("repro.experiments.registry")
io.publish_hooks.append(lambda tmp, path: reg._publish_guard(int(sys.argv[2]), tmp))
io.write_text(Path(sys.argv[1]) / "x.csv", "x\\n")
"""


@pytest.mark.parametrize("parent", ["alive", "gone"])
def test_a_worker_publishes_nothing_once_its_parent_is_gone(tmp_path, parent):
    """The publish guard a worker installs: with its parent alive the file is moved into place; with it gone
    (a parent pid that is not this process's parent any more) the temporary is removed and the process ends."""
    pid = os.getpid() if parent == "alive" else -1
    p = subprocess.run([sys.executable, "-c", _GUARDED, str(tmp_path), str(pid)], cwd=ROOT, capture_output=True,
                       text=True, timeout=300)
    if parent == "alive":
        assert p.returncode == 0, p.stderr
        assert sorted(x.name for x in tmp_path.iterdir()) == ["x.csv"]
    else:
        assert p.returncode == 1, p.stderr
        assert sorted(x.name for x in tmp_path.iterdir()) == []


_MIDDLE = """
import subprocess, sys, time
subprocess.Popen([sys.executable, "-c", sys.argv[1], sys.argv[2]])
time.sleep(300)
"""

_WATCHED = """
import importlib, os, sys, time
from pathlib import Path
reg = importlib.import_module("repro.experiments.registry")
if sys.argv[2] == "fallback":
    importlib.import_module("repro.processes").parent_death_signal = lambda signum: False  # as where there is no prctl: the watching thread alone
reg._die_with_parent(os.getppid())
Path(sys.argv[1], f"started-{os.getpid()}").write_text("")
time.sleep(300)
"""


@pytest.mark.parametrize("how", ["prctl", "fallback"])
def test_a_worker_dies_with_its_parent(tmp_path, how):
    """``_die_with_parent`` in a process whose parent is then SIGKILLed: it ends too (by Linux's
    parent-death signal, or by the thread that watches the parent where that is not available)."""
    script = _WATCHED.replace("sys.argv[1]", repr(str(tmp_path))).replace("sys.argv[2]", repr(how))
    middle = subprocess.Popen([sys.executable, "-c", _MIDDLE, script, ""], cwd=ROOT, start_new_session=True)
    try:
        deadline = time.monotonic() + 120
        while not list(tmp_path.glob("started-*")):
            assert time.monotonic() < deadline and middle.poll() is None
            time.sleep(0.05)
        (marker,) = tmp_path.glob("started-*")
        child = int(marker.name.split("-")[1])
        assert child in _session(middle.pid)
        middle.kill()
        middle.wait()
        for _ in range(100):  # 5 s
            if child not in _session(middle.pid):
                break
            time.sleep(0.05)
        assert child not in _session(middle.pid), f"{how}: the child outlived its parent"
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(middle.pid, signal.SIGKILL)
        middle.wait()


def test_a_worker_whose_parent_died_before_it_was_set_up_ends_at_once(tmp_path):
    """(The race prctl leaves open: the parent died before the signal was asked for.)"""
    code = "import importlib; importlib.import_module('repro.experiments.registry')._die_with_parent(-1); print('ran on')"
    p = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert p.returncode == 1 and "ran on" not in p.stdout


_PROBING = """
from repro.ui import render
render.render_unavailable_reason()
"""


def _children(pid: int) -> set:
    try:
        return {int(c) for t in Path(f"/proc/{pid}/task").iterdir() for c in (t / "children").read_text().split()}
    except OSError:
        return set()


def test_the_render_probe_of_a_killed_worker_ends_with_it(tmp_path):
    """A worker's grandchild, the VTK render probe (repro.ui.render), ends with the process that probes:
    otherwise it would outlive a killed run, unbounded when it hangs (its timeout is the prober's).
    Here it hangs: a ``pyvista`` that never finishes importing."""
    fake = tmp_path / "hang"
    fake.mkdir()
    (fake / "pyvista.py").write_text("import time\ntime.sleep(300)\n")
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(fake), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep))
    prober = subprocess.Popen([sys.executable, "-c", _PROBING], cwd=ROOT, env=env, start_new_session=True,
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 120
        while not (probe := _children(prober.pid)):
            assert time.monotonic() < deadline and prober.poll() is None, "no probe started"
            time.sleep(0.01)
        prober.kill()
        prober.wait()
        for _ in range(100):  # 5 s
            if not probe & set(_session(prober.pid)):
                break
            time.sleep(0.05)
        assert not probe & set(_session(prober.pid)), "the render probe outlived its parent"
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(prober.pid, signal.SIGKILL)
        prober.wait()
