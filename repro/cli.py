"""The ``repro`` command (also ``python -m repro``).

    repro list                      every registered figure/measurement, one line each
    repro run NAME [NAME ...]       write NAME.png and NAME.csv into figures/
    repro all                       run every registered figure (--jobs N: in N processes)
    repro bench attenuation         print speed ratios, write figures/bench_attenuation.csv
    repro bench retrieval           search latency vs database size, write figures/retrieval_latency.csv
                                    (--queries N --factors 1,10,100 --database cmu: e.g. 1,000 queries)
    repro bench adaptation          retarget/adapt cost per frame, write figures/bench_adaptation.csv
    repro bench index               build time and peak memory of the 100x / 1,000x databases and index
    repro bench prepare             query preparation (q retargeted to the actor) per kind of character
    repro bench order               the fighter's order-to-first-frame on the real humanoid rigs
    repro claims                    the claims ledger (figures/claims.md, figures/claims.csv)
    repro data list                 each dataset: present? verified?
    repro data fetch NAME           download (and verify) a dataset into the data folder
    repro app face|fighter          a paper's panel as a web page without code (Voila; --port, --host;
                                    served with a token printed inside the URL, --no-token on loopback only)

Exit status: 0 on success, 2 for an unknown name or bad usage (e.g. ``--out``
naming a file or empty, ``--queries 0``, ``--factors 1,-1``, ``--port 70000``: the
usage line and one ``repro: ...`` line), 1 when a run fails with one of repro's own
errors (the message says why, on one line).  Progress bars (plain tqdm, shown after a
second) go to stderr; the library itself never shows one unless asked (``progress=True``).
"""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

from repro.errors import ReproError, UnknownFigureError

DEFAULT_OUT = "figures"
BENCHES = ("attenuation", "retrieval", "adaptation", "index", "prepare", "order")


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="repro", description="Regenerate the figures and measurements of the two papers.")
    sub = p.add_subparsers(dest="command", required=True)
    sub.add_parser("list", help="list every registered figure or measurement").set_defaults(usage=None)
    for name, helptext in [("run", "run the named figures"), ("all", "run every figure")]:
        sp = sub.add_parser(name, help=helptext)
        sp.set_defaults(usage=sp.format_usage)
        if name == "run":
            sp.add_argument("names", nargs="+", metavar="NAME")
        sp.add_argument("--out", default=DEFAULT_OUT, help="output folder (default: figures)")
        sp.add_argument("--quick", action="store_true", help="reduced sweeps (as CI runs them)")
        sp.add_argument("--force", action="store_true", help="rerun even when inputs and outputs are unchanged")
        sp.add_argument("--face", action="append", default=[], metavar="FILE",
                        help="a .gltf/.glb/.vrm face (ARKit shape names or VRM expressions) added to every Lewis "
                             "figure; repeatable")
        sp.add_argument("--jobs", "-j", type=_jobs, default=1, metavar="N",
                        help="compute the figures without timings in N processes (0: one per CPU); the timing "
                             "figures then run alone (default: 1, all in this process)")
    b = sub.add_parser("bench", help="benchmarks printing ratios against an in-process baseline")
    b.set_defaults(usage=b.format_usage)
    b.add_argument("which", choices=BENCHES)
    b.add_argument("--quick", action="store_true")
    b.add_argument("--out", default=DEFAULT_OUT)
    b.add_argument("--queries", default=None, metavar="N",
                   help="retrieval: queries per database and size (default 200; 100 with --quick or from 1,000x)")
    b.add_argument("--factors", default=None, metavar="F,F,...",
                   help="retrieval: database sizes, comma-separated (default 1,10,100,1000; 1,10 with --quick)")
    b.add_argument("--database", action="append", default=None, metavar="NAME",
                   help="retrieval: a base database (synthetic, cmu); repeatable (default: synthetic, and cmu when present)")
    c = sub.add_parser("claims", help="the claims ledger: each claim, its measured value, a verdict")
    c.set_defaults(usage=c.format_usage)
    c.add_argument("--full", action="store_true", help="measure with the full sweeps (default: the quick ones CI uses)")
    c.add_argument("--out", default=DEFAULT_OUT)
    c.add_argument("--store", action="store_true",
                   help="also rewrite the stored ledger notebook 00 opens with (repro/claims/stored.csv; quick mode, "
                        "with the real data present, as the tests measure it)")
    d = sub.add_parser("data", help="the datasets: list, fetch")
    dsub = d.add_subparsers(dest="data_command", required=True)
    dsub.add_parser("list", help="each dataset, whether present and verified").set_defaults(usage=None)
    f = dsub.add_parser("fetch", help="download and verify datasets")
    f.set_defaults(usage=f.format_usage)
    f.add_argument("datasets", nargs="+", metavar="NAME")
    a = sub.add_parser("app", help="a paper's panel as a web page without code (Voila)")
    a.set_defaults(usage=a.format_usage)
    a.add_argument("which", choices=("face", "fighter"), help="face: Lewis et al. 2005; fighter: Pronost et al.")
    a.add_argument("--port", type=int, default=8866, help="port to serve on, 1..65535 (default: 8866)")
    a.add_argument("--host", default="127.0.0.1",
                   help="address to listen on (default: 127.0.0.1, this machine only; another address is warned about)")
    a.add_argument("--no-browser", action="store_true",
                   help="do not open a browser (never opened without a display; the address is printed)")
    a.add_argument("--no-token", action="store_true",
                   help="serve without the access token (loopback addresses only: anyone on this machine can then "
                        "use the app's kernel)")
    return p


def _jobs(text: str) -> int:
    """``--jobs N``: a whole number >= 0 (0: one per CPU)."""
    import os

    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number of processes, got {text!r}") from None
    if n < 0:
        raise argparse.ArgumentTypeError(f"expected 0 (one per CPU) or more processes, got {n}")
    return n or os.cpu_count() or 1


def _bad_out(out: str) -> str | None:
    """Why ``--out`` cannot be the output folder (it is created when missing), or None."""
    from repro.experiments.registry import output_folder

    try:
        output_folder(out)
    except ReproError as exc:
        return f"--out: {exc}"
    return None


def _run(names, out: str, quick: bool, force: bool = False, faces=(), jobs: int = 1) -> int:
    from tqdm import tqdm  # a plain bar on stderr (never a notebook widget)

    from repro.experiments import registry
    from repro.experiments.registry import run_many

    reg = registry()
    unknown = [n for n in names if n not in reg]
    if unknown:
        print(f"repro: unknown figure {', '.join(map(repr, unknown))}; known: {', '.join(reg)}", file=sys.stderr)
        return 2
    bar = tqdm(total=len(names), desc="figures", unit="fig", delay=1.0, file=sys.stderr)

    def report(name, status, paths):
        if status == "cached":
            tqdm.write(f"{name}: up to date (inputs unchanged; --force to rerun)")
        elif status == "ran":
            for path in paths:
                tqdm.write(f"wrote {path}")
        else:
            tqdm.write(f"repro: {name} {status}", file=sys.stderr)
        bar.update()

    status = run_many(names, out, quick=quick, force=force, on_result=report, progress=True, faces=faces,
                      jobs=jobs)
    bar.close()
    failed = [n for n, s in status.items() if s not in ("ran", "cached")]
    if failed:
        print(f"repro: {len(failed)} of {len(names)} failed: {', '.join(failed)}", file=sys.stderr)
        return 1
    return 0


def _data(args) -> int:
    from repro import data

    if args.data_command == "list":
        print(f"data folder: {data.data_dir()}")
        for name, what in data.DATASETS.items():
            s = data.status(name)
            state = (
                "verified" if s["verified"] == s["files"]
                else "CORRUPT" if s["problems"]
                else "missing" if s["present"] == 0
                else "incomplete"
            )
            print(f"{name:11s} {state:10s} {s['verified']:3d}/{s['files']:<3d} files  {what}")
            for problem in s["problems"][:3]:
                print(f"    {problem}")
        return 0
    bad = [n for n in args.datasets if n not in data.DATASETS]
    if bad:
        print(f"repro: unknown dataset {', '.join(map(repr, bad))}; known: {', '.join(data.DATASETS)}", file=sys.stderr)
        return 2
    for name in args.datasets:
        folder = data.require(name, download=True, progressbar=True)
        print(f"{name}: verified in {folder}")
    return 0


def _claims(args) -> int:
    from repro import claims
    from repro.io import write_csv, write_text

    if args.store and args.full:
        from repro.errors import DataError

        raise DataError("--store keeps the quick ledger (the one the tests measure): drop --full")

    rows = claims.evaluate(quick=not args.full, progress=True)
    for r in rows:
        print(f"{r['id']:4s} {r['embedded_verdict']:15s} {r['real_verdict']:15s} {r['statement'][:90]}")
    print(claims.summary_line(rows))
    out = Path(args.out)
    print(f"wrote {write_text(out / 'claims.md', claims.to_markdown(rows))}")
    print(f"wrote {write_csv(out / 'claims.csv', claims.ledger_table(rows))}")
    if args.store:
        from repro.claims import overview

        print(f"wrote {write_text(overview.STORED, overview.stored_csv(rows))}")
    return 0


def _show_warning(message, category, filename, lineno, file=None, line=None):
    """repro's own warnings as one ``repro: warning: ...`` line on stderr (others as Python shows them)."""
    from repro.errors import ReproWarning

    if issubclass(category, ReproWarning):
        print(f"repro: warning: {message}", file=sys.stderr)
    else:
        sys.stderr.write(warnings.formatwarning(message, category, filename, lineno, line))


def main(argv=None) -> int:
    args = _parser().parse_args(argv)
    with warnings.catch_warnings():
        warnings.showwarning = _show_warning
        return _main(args)


def _one_line(exc) -> str:
    """An error's message on one line (a message of several lines joined with '; ')."""
    return "; ".join(part.strip() for part in str(exc).splitlines() if part.strip()) or type(exc).__name__


def _usage_error(args, why: str) -> int:
    """Bad usage: the command's usage line (as argparse prints it) and one ``repro: ...`` line; exit status 2."""
    usage = getattr(args, "usage", None)
    if usage is not None:
        sys.stderr.write(usage())
    print(f"repro: {_one_line(why)}", file=sys.stderr)
    return 2


def _factors(text: str) -> list:
    """``--factors 1,10,100``: the ints, or ValueError (``1,,2``, ``1,x``, ``1.5``)."""
    return [int(f) for f in text.split(",")]


def _usage_problem(args) -> str | None:
    """Why the arguments are bad usage (checked before any work, --out before it is created), or None.

    Everything argparse's types cannot say alone: the values the library would refuse
    (``--queries 0``, ``--factors 1,-1``, ``--database nope``, a factor asking more memory than
    :data:`repro.checks.MEMORY_BUDGET`, ``--port 70000``, ``--no-token`` off loopback) exit 2, not 1.
    """
    strings = [v for v in vars(args).values() if isinstance(v, str)]
    strings += [x for v in vars(args).values() if isinstance(v, list) for x in v if isinstance(x, str)]
    if any("\0" in v for v in strings):  # only reachable through main(argv): exec's argv has no NUL
        return "an argument contains a NUL character"
    out = getattr(args, "out", None)
    if out is not None and not out.strip():
        return f"--out must name a folder, got {out!r} (the figures would land in the current folder)"
    if any(not f.strip() for f in getattr(args, "face", None) or ()):
        return "--face must name a .gltf, .glb or .vrm file, got ''"
    from repro.errors import RetrievalError

    if args.command == "bench" and (args.queries is not None or args.factors is not None or args.database is not None):
        from repro.bench import retrieval

        if args.which != "retrieval":
            return "--queries, --factors and --database are options of 'repro bench retrieval'"
        try:
            factors = None if args.factors is None else _factors(args.factors)
        except ValueError:
            return f"--factors must be comma-separated ints >= 1, got {args.factors!r}"
        try:
            queries = None if args.queries is None else int(args.queries)
        except ValueError:
            return f"--queries must be a whole number >= 1, got {args.queries!r}"
        try:  # the library's own check (ranges, known databases, the memory the factors ask), before any work
            retrieval.check_bench_arguments(args.database, factors, queries)
        except RetrievalError as exc:  # (data missing to load a base is not usage: a ReproError, exit 1)
            return f"{exc}"
        args.factors, args.queries = factors, queries
    if args.command == "app":
        from repro.ui.app import is_loopback

        if not 1 <= args.port <= 65535:
            return f"--port must be a number in 1..65535, got {args.port}"
        if not args.host.strip():
            return "--host must name an address (an empty one would listen on every interface)"
        if args.no_token and not is_loopback(args.host):
            return (f"--no-token is only allowed on a loopback address (127.0.0.1, ::1, localhost), not --host "
                    f"{args.host!r}: anyone who can reach it could run code in the app's kernel")
    return None


def _main(args) -> int:
    try:
        if (why := _usage_problem(args)) is not None:
            return _usage_error(args, why)
        # every command that writes (run, all, bench, claims) takes --out: refuse a bad one before computing
        # (exit 2, one ``repro: --out: ...`` line and no usage line: the arguments are well formed, the
        # folder they name is not one that can be written)
        if getattr(args, "out", None) is not None and (why := _bad_out(args.out)):
            print(f"repro: {_one_line(why)}", file=sys.stderr)
            return 2
        if args.command == "list":
            from repro.experiments import registry

            for exp in registry().values():
                print(f"{exp.name:28s} [{exp.paper}] {exp.caption}")
            return 0
        if args.command == "run":
            return _run(args.names, args.out, args.quick, args.force, args.face, args.jobs)
        if args.command == "all":
            from repro.experiments import registry

            return _run(list(registry()), args.out, args.quick, args.force, args.face, args.jobs)
        if args.command == "bench":
            from repro.bench import adaptation, attenuation, index_build, order, prepare, retrieval
            from repro.io import write_csv

            run_, fmt, csv_name = {
                "attenuation": (attenuation.bench_attenuation, attenuation.format_attenuation, "bench_attenuation.csv"),
                "retrieval": (retrieval.bench_retrieval, retrieval.format_retrieval, "retrieval_latency.csv"),
                "adaptation": (adaptation.bench_adaptation, adaptation.format_adaptation, "bench_adaptation.csv"),
                "index": (index_build.bench_index_build, index_build.format_index_build, "bench_index_build.csv"),
                "prepare": (prepare.bench_prepare, prepare.format_prepare, "bench_prepare.csv"),
                "order": (order.bench_order, order.format_order, "bench_order.csv"),
            }[args.which]
            extra = {}
            if args.queries is not None or args.factors is not None or args.database is not None:
                # checked by _usage_problem (exit 2 before any work), --factors parsed there
                extra = dict(n_queries=args.queries, factors=args.factors, databases=args.database)
            table = run_(quick=args.quick, progress=True, **extra)
            print(fmt(table))
            print(f"wrote {write_csv(Path(args.out) / csv_name, table)}")
            return 0
        if args.command == "claims":
            return _claims(args)
        if args.command == "data":
            return _data(args)
        if args.command == "app":
            from repro.ui.app import run_app

            return run_app(args.which, args.host, args.port, no_browser=args.no_browser, token=not args.no_token)
    except UnknownFigureError as exc:
        print(f"repro: {_one_line(exc)}", file=sys.stderr)
        return 2
    except ReproError as exc:
        print(f"repro: {_one_line(exc)}", file=sys.stderr)
        return 1
    except OSError as exc:  # e.g. no permission to write into --out: say so, no traceback
        print(f"repro: {_one_line(exc)}", file=sys.stderr)
        return 1
    return 2  # pragma: no cover - argparse enforces the commands


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
