"""The machinery behind ``REPRO_NBVAL_COLD_BUSY=1`` (tests/conftest.py), which .ci/run sets.

The notebooks themselves run under it in CI's one nbval pass (each kernel with
empty caches, every core busy).  Here: that a kernel started after a notebook's
setup really sees empty cache folders, that the burners really load the CPU, and
that everything is undone afterwards.
"""

from __future__ import annotations

import json
import logging
import os
import subprocess
import sys
import time
from pathlib import Path
from types import SimpleNamespace

from tests.conftest import COLD_VARS, ColdBusyNotebooks


def _child_view() -> dict:
    """What a child process (as nbval's kernel is) sees: each cold variable and whether its folder is empty."""
    code = ("import json, os\nprint(json.dumps({v: [os.environ.get(v), os.path.isdir(os.environ.get(v, '')) "
            "and not os.listdir(os.environ[v])] for v in %r}))" % list(COLD_VARS))
    return json.loads(subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                                     timeout=60).stdout)


def _cpu_seconds(pids) -> float:
    tick = os.sysconf("SC_CLK_TCK")
    total = 0
    for pid in pids:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        total += int(fields[11]) + int(fields[12])  # utime + stime
    return total / tick


def test_each_notebook_kernel_starts_cold_on_busy_cores():
    before = {v: os.environ.get(v) for v in COLD_VARS}
    plugin = ColdBusyNotebooks()
    try:
        plugin.pytest_runtest_setup(SimpleNamespace(path=Path("a.ipynb")))
        first = _child_view()
        assert all(empty for _, empty in first.values()), first
        assert all(path.startswith(str(plugin.root)) for path, _ in first.values())
        assert first["HOME"][0] != before["HOME"]
        per_worker = max(1, (os.cpu_count() or 1) // int(os.environ.get("PYTEST_XDIST_WORKER_COUNT") or 1))
        assert len(plugin.burners) == per_worker and all(p.poll() is None for p in plugin.burners)
        pids = [p.pid for p in plugin.burners]
        t0, deadline = _cpu_seconds(pids), time.monotonic() + 20
        while _cpu_seconds(pids) - t0 < 0.5:  # they do burn CPU (a shared machine may give them little)
            assert time.monotonic() < deadline, "the burners used no CPU"
            time.sleep(0.2)

        root_a = plugin.root
        plugin.pytest_runtest_setup(SimpleNamespace(path=Path("a.ipynb")))  # a later cell: same kernel, same folder
        assert plugin.root == root_a
        (root_a / "cache" / "warm").write_text("x")
        plugin.pytest_runtest_setup(SimpleNamespace(path=Path("b.ipynb")))  # the next notebook: cold again
        assert plugin.root != root_a and not root_a.exists()
        assert all(empty for _, empty in _child_view().values())
        burners, root = plugin.burners, plugin.root
        plugin.pytest_runtest_setup(SimpleNamespace(path=Path("test_x.py")))  # not a notebook: all undone
        assert plugin.notebooks == 2
        assert all(p.poll() is not None for p in burners) and not root.exists()
        assert {v: os.environ.get(v) for v in COLD_VARS} == before
        plugin.pytest_runtest_setup(SimpleNamespace(path=Path("c.ipynb")))  # a notebook after other tests
        burners, root = plugin.burners, plugin.root
        assert burners and root.exists()
    finally:
        plugin.pytest_sessionfinish(None, 0)
    assert all(p.poll() is not None for p in burners)
    assert not root.exists()
    assert {v: os.environ.get(v) for v in COLD_VARS} == before


def test_a_burner_stops_by_itself_when_its_parent_dies():
    code = ("import subprocess, sys\nsys.path.insert(0, %r)\nfrom tests.conftest import start_burners\n"
            "print(start_burners(1)[0].pid, flush=True)\n" % str(Path(__file__).resolve().parents[1]))
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60,
                       env={**os.environ, "REPRO_NBVAL_COLD_BUSY": "0"})
    pid = int(p.stdout.split()[0])
    deadline = time.monotonic() + 10
    while Path(f"/proc/{pid}").exists() and Path(f"/proc/{pid}/stat").read_text().split()[2] != "Z":
        assert time.monotonic() < deadline, f"burner {pid} outlived its parent"
        time.sleep(0.1)


def test_project_kernels_do_not_announce_a_font_cache_build(tmp_path, monkeypatch):
    # scripts/setup.sh installs scripts/ipython/ipython_kernel_config.py into the venv: a kernel of
    # this environment starts with matplotlib's font-cache announcement (a first-use message on a
    # slow machine) silenced, even with an empty IPYTHONDIR and HOME
    from jupyter_client.manager import start_new_kernel

    installed = Path(sys.prefix) / "etc" / "ipython" / "ipython_kernel_config.py"
    source = Path(__file__).resolve().parents[1] / "scripts" / "ipython" / "ipython_kernel_config.py"
    assert installed.read_text() == source.read_text(), "run scripts/setup.sh"
    for var in ("HOME", "IPYTHONDIR", "MPLCONFIGDIR"):
        monkeypatch.setenv(var, str(tmp_path / var))
    km, kc = start_new_kernel(kernel_name="python3")
    try:
        seen = []
        kc.execute_interactive(
            "import logging; print(logging.getLogger('matplotlib.font_manager').getEffectiveLevel())",
            output_hook=lambda m: seen.append(m["content"].get("text", "")) if m["msg_type"] == "stream" else None,
            timeout=120,
        )
    finally:
        kc.stop_channels()
        km.shutdown_kernel(now=True)
    assert "".join(seen).strip() == str(logging.ERROR)
