"""Benchmarks run and report what they promise (their numbers are never asserted as times)."""

import pandas as pd
import pytest

from repro import cli
from repro.bench import adaptation, retrieval


def test_bench_retrieval_columns_and_methods():
    t = retrieval.bench_retrieval(databases=["synthetic"], factors=(1, 2), n_queries=20, progress=False)
    assert {"n_clips", "n_poses", "method", "p50_ms", "p99_ms"} <= set(t.columns)
    assert set(t.method) == {"pruned", "exact", "exhaustive", "kdtree"}
    assert (t[t.method == "exhaustive"].differs_from_exhaustive == 0).all()
    assert (t[t.method == "exact"].n_differs == 0).all()  # the exact search is the exhaustive optimum
    assert t.n_poses.nunique() == 2 and (t.p50_ms > 0).all()
    s = retrieval.retrieval_summary(t)["synthetic"]
    assert s["largest_factor"] == 2 and s["speedup_vs_exhaustive_at_largest"] > 0
    assert "pruned vs exhaustive" in retrieval.format_retrieval(t)
    assert "exact vs exhaustive" in retrieval.format_retrieval(t)
    assert "synthetic x2: exact vs exhaustive p50" in retrieval.format_retrieval(t)  # the ratios per size


def test_bench_adaptation_reports_per_frame_costs():
    t = adaptation.bench_adaptation(quick=True, progress=False)
    assert "synthetic punch" in set(t["clip"])
    assert (t.retarget_plus_adapt_over_fk > 0).all() and (t.load_convert_ms > 0).all()
    assert "paper 88 us" in adaptation.format_adaptation(t)


def test_bench_cli_writes_the_contract_csv(tmp_path, monkeypatch, capsys):
    full = retrieval.bench_retrieval
    small = lambda quick, progress=False: full(databases=["synthetic"], factors=(1,), n_queries=10, progress=False)  # noqa: E731
    monkeypatch.setattr(retrieval, "bench_retrieval", small)
    assert cli.main(["bench", "retrieval", "--out", str(tmp_path)]) == 0
    t = pd.read_csv(tmp_path / "retrieval_latency.csv")
    assert list(t.columns[:7]) == ["database", "factor", "n_clips", "n_poses", "method", "p50_ms", "p99_ms"]
    assert "base p50" in capsys.readouterr().out
    with pytest.raises(SystemExit):
        cli.main(["bench", "nope"])


def test_the_package_forwards_the_flat_names_to_their_modules():
    """``from repro.bench import bench_retrieval`` (notebook 03, older code) reaches the module's function."""
    from repro import bench
    from repro.bench import attenuation

    assert bench.bench_retrieval is retrieval.bench_retrieval and bench.retrieval_summary is retrieval.retrieval_summary
    assert bench.bench_attenuation is attenuation.bench_attenuation and bench.format_adaptation is adaptation.format_adaptation
    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        bench.nope  # noqa: B018  (the attribute access is the test)


def test_bench_index_build_columns_and_goals():
    from repro.bench import index_build

    t = index_build.bench_index_build(factors=(2,), baseline_variants=5)
    assert list(t.factor) == [2] and t.n_poses.iloc[0] > 0 and t.k.iloc[0] >= 1
    assert t.augment_peak_gb.iloc[0] > 0 and t.index_peak_gb.iloc[0] > 0 and t.per_variant_augment_s.iloc[0] > 0
    assert t.pose_dtype.iloc[0] == "float64"
    assert "per-variant path" in index_build.format_index_build(t)


def test_bench_prepare_rows_and_equality():
    from repro.bench import prepare

    t = prepare.bench_prepare(quick=True, n_queries=8)
    assert list(t.case) == ["uniform", "proportions", "across_trees"] and (t.n_queries == 8).all()
    assert (t.prepare_p50_ms > 0).all()
    p = t.set_index("case").loc["proportions"]
    assert p.step_p50_ms > 0 and p.baseline_step_p50_ms > 0 and p.step_speedup > 0
    assert (t.max_abs_diff == 0).all()  # the plan's q_r is retarget()'s, bit for bit
    assert "retarget() " in prepare.format_prepare(t) and "goal prepare < 1 ms" in prepare.format_prepare(t)


def test_bench_retrieval_cli_options_reach_the_benchmark(tmp_path, monkeypatch):
    """``--queries/--factors/--database`` are passed on; a given number of queries is honoured, not capped."""
    seen, full = {}, retrieval.bench_retrieval

    def fake(quick, progress=False, **kw):
        seen.update(kw)
        return full(databases=["synthetic"], factors=(1,), n_queries=3, progress=False)

    monkeypatch.setattr(retrieval, "bench_retrieval", fake)
    argv = ["bench", "retrieval", "--queries", "1000", "--factors", "1,10,100", "--database", "synthetic",
            "--out", str(tmp_path)]
    assert cli.main(argv) == 0
    assert seen == {"n_queries": 1000, "factors": [1, 10, 100], "databases": ["synthetic"]}


@pytest.mark.parametrize("argv", [
    ["bench", "retrieval", "--factors", "1,x"], ["bench", "retrieval", "--factors", "0"],
    ["bench", "retrieval", "--queries", "0"], ["bench", "retrieval", "--database", "nope"],
    ["bench", "adaptation", "--queries", "5"],
])
def test_bench_retrieval_cli_refuses_bad_options(argv, tmp_path, capsys):
    assert cli.main(argv + ["--out", str(tmp_path)]) in (1, 2)
    assert "repro:" in capsys.readouterr().err
    assert not (tmp_path / "retrieval_latency.csv").exists()


@pytest.mark.parametrize("kw", [dict(databases=["nope"]), dict(databases=[]), dict(factors=(0,)), dict(factors=(1.5,)),
                                dict(factors=()), dict(factors=5), dict(n_queries=0), dict(n_queries="10")])
def test_bench_retrieval_refuses_bad_arguments(kw):
    from repro.errors import RetrievalError

    with pytest.raises(RetrievalError):
        retrieval.bench_retrieval(progress=False, **kw)


@pytest.mark.parametrize("kw", [dict(factors="12"), dict(factors=(1, 10**9)), dict(factors=(10**400,)), dict(factors=(True,)),
                                dict(n_queries=10**12), dict(databases=5), dict(quick="yes"), dict(seed=-1),
                                dict(seed="x"), dict(progress=None), dict(database="synthetic")])
def test_bench_retrieval_refuses_more_bad_arguments(kw):
    """Every argument checked at the entry (issue 23 sections 3 and 6): a RetrievalError, never a bare one."""
    from repro.errors import RetrievalError

    with pytest.raises(RetrievalError):
        retrieval.bench_retrieval(**kw)


def test_check_bench_arguments_checks_the_memory_the_factors_ask_before_building():
    """``factors=(10**9,)`` asked numpy for 67-99 GiB (issue 23 section 3): refused from the base's size."""
    from repro.errors import RetrievalError

    bases = {}
    with pytest.raises(RetrievalError, match=r"factor 100000 \(the synthetic database of \d+ clips.*GiB.*budget"):
        retrieval.check_bench_arguments(["synthetic"], (1, 100000), 10, bases=bases)
    assert set(bases) == {"synthetic"}  # the base the estimate came from, for the caller to reuse
    assert retrieval.check_bench_arguments(["synthetic"], (1, 10), 10, bases=bases) == (["synthetic"], (1, 10), 10)
    assert retrieval.check_bench_arguments(None, None, None) == (None, None, None)  # the defaults, nothing loaded


@pytest.mark.parametrize("entry, kw", [
    ("attenuation.bench_attenuation", dict(seed=-1)), ("attenuation.bench_attenuation", dict(quick="yes")),
    ("attenuation.bench_attenuation_scaling", dict(progress=None)), ("adaptation.bench_adaptation", dict(quick=1)),
    ("prepare.bench_prepare", dict(n_queries=10**12)), ("prepare.bench_prepare", dict(n_queries=0)),
    ("prepare.bench_prepare", dict(seed="x")), ("index_build.bench_index_build", dict(factors=(2, 10**9))),
    ("index_build.bench_index_build", dict(factors=(0,))), ("index_build.bench_index_build", dict(factors=(10**400,))), ("index_build.bench_index_build", dict(database="nope")),
    ("index_build.bench_index_build", dict(database=None)), ("index_build.bench_index_build", dict(baseline_variants=0)),
])
def test_every_bench_entry_checks_its_arguments_first(entry, kw):
    """The other benchmarks' arguments: a ReproError naming the bad one before any work (issue 23 section 6)."""
    import importlib

    from repro.errors import ReproError

    module, name = entry.split(".")
    func = getattr(importlib.import_module(f"repro.bench.{module}"), name)
    with pytest.raises(ReproError, match=next(iter(kw)).replace("factors", "factor")):
        func(**kw)


@pytest.mark.data("cmu-bvh")  # the formats corpus is staged with the mocap data
def test_bench_order_rows_and_same_strikes():
    """``repro bench order``: a row per real rig, the streamed first frame and the whole-clip baseline
    give the same strikes, and the compiled CCD and the numpy one the same to rounding; bad arguments
    refused first."""
    from repro.bench import order
    from repro.errors import ReproError

    t = order.bench_order(quick=True)
    ok = t[t.refused == ""]
    assert len(ok) >= 1 and ok.same_strikes.all() and ok.same_strikes_ccd.all()
    assert (ok.first_frame_p50_ms > 0).all() and (ok.first_frame_p99_ms >= ok.first_frame_p50_ms).all()
    assert (ok.numpy_ccd_p99_ms >= ok.numpy_ccd_p50_ms).all()
    text = order.format_order(t)
    assert "first frame p50" in text and "vs numpy CCD" in text and f"of {len(ok)} rigs under 33.3 ms" in text
    for kw in (dict(n_orders=0), dict(n_orders=10**9), dict(seed="x"), dict(quick=1)):
        with pytest.raises(ReproError, match=next(iter(kw))):
            order.bench_order(**kw)
