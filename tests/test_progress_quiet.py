"""Progress never changes what a computation prints (issue 9, section 1).

Library and benchmark functions show no bar unless asked (``progress=True``);
the CLI asks, and its bars are plain tqdm on stderr.  A first-use download
(pooch) prints nothing either.  Speed must not matter: the tests make a step
slower than tqdm's one-second ``delay``.
"""

from __future__ import annotations

import importlib
import logging
import time

import pytest

from repro import bench
from repro.bench import attenuation as bench_attenuation_module


@pytest.fixture
def slow_small_bench(monkeypatch):
    """bench_attenuation on the small procedural face only, each timing step made 0.6 s slower."""
    from repro.blendshapes import load_model

    monkeypatch.setattr(bench_attenuation_module, "_models", lambda quick: iter([load_model("procedural")]))
    fast = bench.median_time

    def slow(fn, args_list):
        time.sleep(0.6)
        return fast(fn, args_list[:2])

    monkeypatch.setattr(bench_attenuation_module, "median_time", slow)


def test_bench_attenuation_prints_nothing_by_default_however_slow(slow_small_bench, capfd):
    table = bench.bench_attenuation(quick=True)
    assert len(table) == 2
    out, err = capfd.readouterr()
    assert (out, err) == ("", "")


def test_bench_attenuation_progress_is_a_plain_bar_on_stderr(slow_small_bench, capfd):
    bench.bench_attenuation(quick=True, progress=True)
    out, err = capfd.readouterr()
    assert out == "" and "bench attenuation" in err and "2/2" in err


@pytest.mark.parametrize("fn", ["bench_attenuation", "bench_attenuation_scaling", "bench_retrieval", "bench_adaptation"])
def test_every_benchmark_defaults_to_no_progress(fn):
    import inspect

    assert inspect.signature(getattr(bench, fn)).parameters["progress"].default is False


def test_experiments_get_progress_only_when_asked_and_only_if_they_take_it():
    from repro.experiments.registry import Experiment, Result, call_experiment

    seen = []

    def with_bar(quick=False, progress=False):
        seen.append(progress)
        return Result(None)

    def without(quick=False):
        return Result(None)

    e = Experiment("x", "x", with_bar, __name__, "lewis2005")
    call_experiment(e, quick=True)
    call_experiment(e, quick=True, progress=True)
    assert seen == [False, True]
    assert call_experiment(Experiment("y", "y", without, __name__, "lewis2005"), progress=True).table is None


def test_claims_evaluate_passes_progress_through(monkeypatch, quick_figures):
    registry_mod = importlib.import_module("repro.experiments.registry")  # (the package attribute is the function)
    from repro import claims

    attenuation_claims = [c for c in claims.LEDGER if c.figure == "attenuation_speed"]
    assert attenuation_claims
    calls = []
    quick_figures("attenuation_speed")  # computed before the spy answers from it

    def spy(e, *, quick=False, progress=False):  # what is asked for; the numbers are the session's quick ones
        calls.append((e.name, progress))
        assert quick
        return quick_figures(e.name)

    monkeypatch.setattr(registry_mod, "call_experiment", spy)
    claims.evaluate(quick=True, claims=attenuation_claims[:1])
    assert calls == [("attenuation_speed", False)]


def test_cli_turns_progress_on(monkeypatch, tmp_path):
    registry_mod = importlib.import_module("repro.experiments.registry")  # (the package attribute is the function)
    from repro import cli

    got = {}

    def fake_run_many(names, out, **kw):
        got.update(kw)
        return {n: "ran" for n in names}

    monkeypatch.setattr(registry_mod, "run_many", fake_run_many)
    assert cli.main(["run", "fig2_interference", "--out", str(tmp_path)]) == 0
    assert got["progress"] is True


def test_a_first_use_download_logs_nothing(monkeypatch, tmp_path):
    """pooch logs "Downloading data from ..." at INFO on stderr: silenced unless progress was asked for."""
    import pooch

    from repro import data

    records = []

    class Keep(logging.Handler):
        def emit(self, record):
            records.append(record.getMessage())

    def fake_retrieve(url, known_hash, fname, path, progressbar):
        pooch.get_logger().info("Downloading data from '%s' to file '%s'.", url, fname)
        (path / fname).write_bytes(b"x")
        if progressbar:
            progressbar.close()
        return str(path / fname)

    monkeypatch.setattr(pooch, "retrieve", fake_retrieve)
    handler = Keep()
    pooch.get_logger().addHandler(handler)
    try:
        entry = next(iter(data.registry().values()))
        data._download(entry, "https://example.invalid/f", tmp_path)
        assert records == []
        data._download(entry, "https://example.invalid/f", tmp_path, progressbar=True)  # the CLI: messages shown
        assert len(records) == 1 and not pooch.get_logger().filters
    finally:
        pooch.get_logger().removeHandler(handler)


#: the figures whose full run takes more than a second or so (issue 15, item 6: each shows progress in `repro all`)
SLOW_FIGURES = ("adapted_motions", "attenuation_speed", "cross_skeleton", "database_vs_adaptation", "latency_breakdown",
                "retargeting_morphologies", "retrieval_latency")


@pytest.mark.parametrize("name", SLOW_FIGURES)
def test_slow_figures_take_progress_and_default_to_none(name):
    import inspect

    from repro.experiments import get

    assert inspect.signature(get(name).func).parameters["progress"].default is False


def test_figure_bars_are_plain_stderr_bars_only_when_asked(capfd):
    from repro.experiments.progress import bar

    for progress in (False, True):
        for _ in bar(range(2), desc="a slow step", unit="step", progress=progress):
            time.sleep(0.7)  # slower than the one-second delay in all
        out, err = capfd.readouterr()
        assert out == ""
        assert ("a slow step" in err and "2/2" in err) if progress else err == ""
