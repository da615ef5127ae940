"""The argument fuzzer: hostile values for every parameter of the public API (issue 23, section 8).

Each call runs in a CHILD process (``python -m tests.fuzz.arguments MODULE``) under an address-space
limit (``RLIMIT_AS``, :data:`RLIMIT_AS`) and with ``REPRO_MEMORY_BUDGET`` set to :data:`BUDGET` (so what
:func:`repro.checks.check_alloc` lets through fits the limit), with a wall-clock limit per call
enforced by the parent, which kills and restarts the child.  The outcome rule, for every call:

* it raises a :class:`repro.errors.ReproError` (any subclass): fine;
* or it returns, and every float of the result is finite (arrays, dataclasses, repro objects, tuples,
  lists, dicts, pandas DataFrames/Series are walked);
* never another exception (``TypeError``, ``KeyError``, ``MemoryError``, LAPACK errors ...), never a
  RuntimeWarning from repro (turned into an error in the child, as the test suite does), never a dead
  child (segfault, out of memory), never a call past its time limit.

And the unmutated call of every case must succeed (otherwise only error paths would be fuzzed).

How an area adds its cases
--------------------------
Write ``tests/fuzz/test_fuzz_arguments_<area>.py`` with a list ``CASES`` of :class:`Case` at module
level and one test calling :func:`check`::

    from tests.fuzz.arguments import Case, check

    @functools.cache                # shared, expensive fixtures: build once per child
    def _model():
        from repro.blendshapes.faces.procedural import procedural_model
        return procedural_model()

    def _solve():
        m = _model()
        return m.solve, dict(w1=np.zeros(m.n_shapes), selected=[0])   # callable, VALID kwargs

    CASES = [
        Case("BlendshapeModel.solve", _solve, {"w1": "array", "selected": "index_array"}),
        ...
    ]

    def test_blendshapes_arguments():
        check(__name__)

* ``setup()`` returns ``(callable, kwargs)``: a fresh call each time (build a new object when the
  method mutates it; cache only what the call does not change).  Only keyword arguments are
  substituted: wrap a positional-only callable in a lambda with named parameters.  Import the
  library inside ``setup`` or module level, as you like: the module is imported in the child.
* ``params`` maps each parameter to fuzz to its kind, a key of :data:`KINDS` ("int", "real",
  "array", "index_array", "str", "choice", "bool", "path", "callable", "mapping", "any").  Every
  kind gets the :data:`COMMON` values plus its own extras; a parameter absent from the valid kwargs
  is added (an optional argument).  Kinds "array", "index_array" and "real" also get
  :data:`MUTATIONS` of the VALID value (right shape, hostile content: a NaN, 1e300 times it, one
  element short, as complex ...): give a realistic valid value, they reach past the shape checks.
  ``extra`` (``{param: {label: factory}}``) adds values of your own.
* ``time_limit`` (s) per call, default :data:`TIME_LIMIT`; ``nonfinite_ok``: ``True`` when a NaN/inf
  in the result is the documented answer, or a set of the dict keys / attribute names where it is
  (``{"alpha"}``: a table's "not applicable" column); elsewhere in the result it is still a failure.
* Values are named by a label (``"nan"``, ``"10**12"``...) and built in the child by a factory
  (fresh arrays each call).

The runner substitutes every value of every parameter, one at a time, and then a few seeded pairs
(two parameters at once): ``PAIRS`` per case, ``REPRO_FUZZ_ARGS=full`` for ``FULL_PAIRS``.
``REPRO_FUZZ_ARGS_CASE=substring`` restricts a run to the cases whose name contains it.  A case
stops after :data:`MAX_DEAD` timeouts or crashes (each costs its time limit and a restart).
A failure lists every failing (case, parameters = values, outcome, exception, last traceback line).
Run one area from the shell: ``python -m tests.fuzz.arguments --run tests.fuzz.test_fuzz_arguments_blendshapes``.
"""

from __future__ import annotations

import dataclasses
import importlib
import json
import math
import os
import random
import resource
import sys
import traceback
import warnings
from pathlib import Path
from typing import Callable

from tests.fuzz import harness
from tests.fuzz.worker import NonFinite, check_finite  # the one finite-result walker of both fuzzers

REPO = Path(__file__).resolve().parents[2]
#: Address-space limit of the child; numpy + scipy + pandas + repro imports take ~0.5 GiB.
RLIMIT_AS = 3 << 30
#: REPRO_MEMORY_BUDGET in the child: an allocation the library accepts must fit under RLIMIT_AS.
BUDGET = 1 << 30
#: Seconds one call may take (the parent kills the child past it).
TIME_LIMIT = 10.0
#: A case stops after this many timeouts/crashes (each costs its time limit and a restart of the child).
MAX_DEAD = 3
#: Seeded pairs of hostile values per case (default run, and ``REPRO_FUZZ_ARGS=full``).
PAIRS = 4
FULL_PAIRS = 60


# ------------------------------------------------------------------ the table of hostile values
def _np():
    import numpy as np

    return np


class _Opaque:
    """An object of no known kind (``object()`` with a readable repr)."""

    def __repr__(self):
        return "<opaque object>"


#: label -> factory; every parameter of every kind gets these.
COMMON: dict[str, Callable] = {
    "'x'": lambda: "x",
    "''": lambda: "",
    "None": lambda: None,
    "nan": lambda: math.nan,
    "inf": lambda: math.inf,
    "-inf": lambda: -math.inf,
    "-1": lambda: -1,
    "0": lambda: 0,
    "10**12": lambda: 10**12,
    "10**30": lambda: 10**30,
    "1e300": lambda: 1e300,
    "complex(1,1)": lambda: complex(1, 1),
    "True": lambda: True,
    "array([])": lambda: _np().zeros(0),
    "zeros((2,3,4))": lambda: _np().zeros((2, 3, 4)),
    "array([1,nan])": lambda: _np().array([1.0, math.nan]),
    "array(1.0)": lambda: _np().array(1.0),
    "['a','b']": lambda: ["a", "b"],
    "object()": lambda: _Opaque(),
}

#: kind -> extra label -> factory
KINDS: dict[str, dict[str, Callable]] = {
    "any": {},
    "int": {
        "1.5": lambda: 1.5,
        "-10**12": lambda: -(10**12),
        "2**63": lambda: 2**63,
        "int64(2**62)": lambda: _np().int64(2**62),
        "'3'": lambda: "3",
    },
    "real": {
        "-1e300": lambda: -1e300,
        "float64(nan)": lambda: _np().float64("nan"),
        "1e-320": lambda: 1e-320,
        "'0.5'": lambda: "0.5",
        "array([0.5])": lambda: _np().array([0.5]),
    },
    "array": {
        "[[1],[1,2]]": lambda: [[1.0], [1.0, 2.0]],
        "array(['a'])": lambda: _np().array(["a", "b"]),
        "object array": lambda: _np().array([None, 1.0], dtype=object),
        "array([inf])": lambda: _np().array([math.inf]),
        "full(3,1e300)": lambda: _np().full(3, 1e300),
        "complex array": lambda: _np().ones(3, dtype=complex),
        "zeros((0,3))": lambda: _np().zeros((0, 3)),
        "zeros(10**7)": lambda: _np().zeros(10**7),
    },
    "index_array": {
        "[-1]": lambda: [-1],
        "[10**6]": lambda: [10**6],
        "[0.5]": lambda: [0.5],
        "[0,0]": lambda: [0, 0],
        "[2**63]": lambda: [2**63],
        "array([1.5])": lambda: _np().array([1.5]),
        "array([True,False])": lambda: _np().array([True, False]),
        "range(10**12)": lambda: range(10**12),
    },
    "str": {
        "'\\x00'": lambda: "\x00",
        "b'x'": lambda: b"x",
        "'x'*100000": lambda: "x" * 100000,
    },
    "choice": {
        "'\\x00'": lambda: "\x00",
        "b'x'": lambda: b"x",
        "'X '": lambda: "X ",
        "('a',)": lambda: ("a",),
    },
    "bool": {
        "2": lambda: 2,
        "'true'": lambda: "true",
        "'false'": lambda: "false",
        "bool_(True)": lambda: _np().bool_(True),
    },
    "path": {
        "'\\x00'": lambda: "a\x00b",
        "'/dev/zero'": lambda: "/dev/zero",
        "'/'": lambda: "/",
        "'../../../../etc/passwd'": lambda: "../../../../etc/passwd",
        "b'/tmp'": lambda: b"/tmp",
    },
    "callable": {
        "raising callable": lambda: _raiser,
        "1": lambda: 1,
        "lambda: nan": lambda: (lambda *a, **k: math.nan),
    },
    "mapping": {
        "{}": lambda: {},
        "{'x': 1}": lambda: {"x": 1},
        "[('a', 1)]": lambda: [("a", 1)],
        "{1: nan}": lambda: {1: math.nan},
    },
}
KINDS["index"] = dict(KINDS["int"])


def _like(valid, fill):
    a = _np().array(valid, dtype=float, copy=True)
    if a.size:
        a.reshape(-1)[a.size // 2] = fill
    return a


#: kind -> label -> function of the VALID value (applied when the case's valid kwargs hold the
#: parameter): right-shaped hostile arrays, which reach the numerics past the shape checks.
MUTATIONS: dict[str, dict[str, Callable]] = {
    "array": {
        "valid with a nan": lambda v: _like(v, math.nan),
        "valid with an inf": lambda v: _like(v, math.inf),
        "valid with 1e308": lambda v: _like(v, 1e308),
        "valid * 1e300": lambda v: _np().asarray(v, dtype=float) * 1e300,
        "valid * -1e300": lambda v: _np().asarray(v, dtype=float) * -1e300,
        "valid * 1e-300": lambda v: _np().asarray(v, dtype=float) * 1e-300,
        "valid all zero": lambda v: _np().zeros_like(_np().asarray(v, dtype=float)),
        "valid + 1j": lambda v: _np().asarray(v, dtype=float) + 1j,
        "valid as float32": lambda v: _np().asarray(v, dtype=_np().float32),
        "valid as longdouble * 1e4000": lambda v: _np().asarray(v, dtype=_np().longdouble) * _np().longdouble("1e4000"),
        "valid one short": lambda v: _np().asarray(v, dtype=float).reshape(-1)[:-1],
        "valid transposed": lambda v: _np().asarray(v, dtype=float).T.copy(),
        "valid as a list": lambda v: _np().asarray(v).tolist(),
        "valid with an extra axis": lambda v: _np().asarray(v, dtype=float)[None],
    },
    "index_array": {
        "valid negated - 1": lambda v: -_np().asarray(v, dtype=_np().int64) - 1,
        "valid + 10**9": lambda v: _np().asarray(v, dtype=_np().int64) + 10**9,
        "valid as float": lambda v: _np().asarray(v, dtype=float),
        "valid as uint64 max": lambda v: _np().full(_np().shape(v), _np().iinfo(_np().uint64).max, dtype=_np().uint64),
        "valid repeated": lambda v: _np().concatenate([_np().ravel(v), _np().ravel(v)]),
        "valid as a 2-D column": lambda v: _np().asarray(v).reshape(-1, 1),
        "valid reversed": lambda v: _np().asarray(v)[::-1].copy(),
    },
    "real": {
        "valid * 1e300": lambda v: v * 1e300 if isinstance(v, (int, float)) and not isinstance(v, bool) else 1e300,
        "valid as float32": lambda v: _np().float32(v) if isinstance(v, (int, float)) else _np().float32(1),
        "5e-324": lambda v: 5e-324,
    },
}


def _raiser(*args, **kw):
    raise RuntimeError("a user callback failed")


@dataclasses.dataclass
class Case:
    """A public callable and how to call it validly (see the module docstring)."""

    name: str
    setup: Callable[[], tuple]
    params: dict[str, str]
    extra: dict[str, dict[str, Callable]] = dataclasses.field(default_factory=dict)
    time_limit: float = TIME_LIMIT
    nonfinite_ok: bool | frozenset | set = False

    def values(self, param: str) -> dict[str, Callable]:
        """label -> factory (no argument) or, for the labels of :data:`MUTATIONS`, a function of the valid value."""
        kind = self.params[param]
        if kind not in KINDS:
            raise KeyError(f"case {self.name}: unknown kind {kind!r} for {param} (known: {sorted(KINDS)})")
        return {**COMMON, **KINDS[kind], **MUTATIONS.get(kind, {}), **self.extra.get(param, {})}


def plan(cases: list[Case], pairs: int | None = None) -> list[tuple[str, list[tuple[str, str]]]]:
    """Every call to make: ``(case, [(param, label), ...])``; the unmutated call first in each case."""
    if pairs is None:
        pairs = FULL_PAIRS if os.environ.get("REPRO_FUZZ_ARGS", "") == "full" else PAIRS
    only = os.environ.get("REPRO_FUZZ_ARGS_CASE", "")
    calls = []
    for case in cases:
        if only and only not in case.name:
            continue
        calls.append((case.name, []))
        for p in case.params:
            calls.extend((case.name, [(p, lab)]) for lab in case.values(p))
        if len(case.params) >= 2:
            rng = random.Random(f"{case.name}/pairs")  # deterministic: a str seed is hashed with sha512
            for _ in range(pairs):
                p1, p2 = rng.sample(sorted(case.params), 2)
                calls.append((case.name, [(p1, rng.choice(sorted(case.values(p1)))),
                                          (p2, rng.choice(sorted(case.values(p2))))]))
    return calls


# ------------------------------------------------------------------ the outcome rule (child side)
def _call(cases: dict[str, Case], case_name: str, subs: list) -> dict:
    from repro.errors import ReproError

    case = cases[case_name]
    stage = "setup"
    try:
        fn, kwargs = case.setup()
        kwargs = dict(kwargs)
        for param, label in subs:
            make = case.values(param)[label]
            if label in MUTATIONS.get(case.params[param], {}) and label not in case.extra.get(param, {}):
                try:
                    kwargs[param] = make(kwargs[param])
                except Exception:  # noqa: BLE001 - the valid value is not an array (a model, None): not applicable
                    return dict(outcome="ok", skipped=True)
            else:
                kwargs[param] = make()
        stage = "call"
        result = fn(**kwargs)
        stage = "result"
        if case.nonfinite_ok is not True:
            check_finite(result, skip=frozenset(case.nonfinite_ok or ()), public_only=True)
    except ReproError as exc:
        if stage == "setup":
            return dict(outcome="error", type=type(exc).__name__, message=f"setup failed: {exc}"[:2000],
                        stage=stage, traceback=traceback.format_exc()[-3000:])
        return dict(outcome="repro_error", type=type(exc).__name__, message=str(exc)[:500], stage=stage)
    except NonFinite as exc:
        return dict(outcome="nonfinite", type="NonFinite", message=str(exc)[:1000], stage=stage)
    except BaseException as exc:  # noqa: BLE001 - the point: anything else is a defect
        if isinstance(exc, (KeyboardInterrupt, SystemExit)):
            raise
        tb = "".join(traceback.format_exception(exc))
        name = type(exc).__qualname__
        if type(exc).__module__ not in ("builtins", None):
            name = f"{type(exc).__module__}.{name}"
        try:
            msg = str(exc)[:1000]
        except BaseException:  # noqa: BLE001
            msg = "<str() failed>"
        exc = None  # drop frames (and big arrays) before replying
        return dict(outcome="error", type=name, message=msg, stage=stage, traceback=tb[-3000:])
    return dict(outcome="ok")


def child_main(module: str) -> None:
    """The child: import ``module`` (its ``CASES``), then answer one JSON request a line."""
    proto = os.fdopen(os.dup(1), "w", buffering=1)
    os.dup2(2, 1)  # library prints cannot corrupt the protocol
    sys.stdout = sys.stderr
    import faulthandler

    faulthandler.enable()
    resource.setrlimit(resource.RLIMIT_AS, (RLIMIT_AS, RLIMIT_AS))

    def reply(**kw):
        proto.write(json.dumps(kw) + "\n")
        proto.flush()

    try:
        import numpy  # noqa: F401

        import repro

        cases = {c.name: c for c in importlib.import_module(module).CASES}
    except BaseException as exc:  # noqa: BLE001
        reply(outcome="broken", message=f"imports failed: {type(exc).__name__}: {exc}")
        return
    # the test suite's policy (pyproject filterwarnings): a RuntimeWarning from repro is an error
    warnings.filterwarnings("ignore", category=Warning)
    warnings.filterwarnings("error", category=RuntimeWarning, module=r"repro\..*")
    reply(outcome="ready", repro_file=repro.__file__)
    for line in sys.stdin:
        req = json.loads(line)
        reply(**_call(cases, req["case"], [tuple(s) for s in req["subs"]]))


# ------------------------------------------------------------------ the parent
class _Child(harness.Worker):
    """The reader fuzzer's worker handling (restart after a crash/timeout), running :func:`child_main`."""

    def __init__(self, module: str, log_dir: str | None = None):
        super().__init__({}, rlimit_as=RLIMIT_AS, time_limit=TIME_LIMIT, log_dir=log_dir)
        self.module = module

    def start(self) -> dict:
        import subprocess

        env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1", MKL_NUM_THREADS="1",
                   PYTHONPATH=os.pathsep.join([str(REPO)] + [p for p in [os.environ.get("PYTHONPATH")] if p]),
                   MPLBACKEND="Agg", REPRO_OFFLINE="1", PYTHONHASHSEED="0", REPRO_MEMORY_BUDGET=str(BUDGET), TMPDIR=self._child_tmp())
        self.log = Path(self.log_dir) / f"args-{self.restarts}.log"
        self._log_fh = open(self.log, "wb")
        self.proc = subprocess.Popen([sys.executable, "-m", "tests.fuzz.arguments", "--child", self.module],
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=self._log_fh,
                                     cwd=REPO, env=env)
        self._buf = b""
        ready = self._reply(harness.READY_LIMIT)
        if ready is None or ready.get("outcome") != "ready":
            tail = self.log.read_text(errors="replace")[-3000:]
            self.stop()
            raise RuntimeError(f"argument fuzz child did not start: {ready}\n{tail}")
        if not Path(ready["repro_file"]).resolve().is_relative_to(REPO):
            self.stop()
            raise RuntimeError(f"the child imported {ready['repro_file']}, not the checkout {REPO}")
        return ready

    def call(self, case: str, subs: list, time_limit: float) -> dict:
        if self.proc is None or self.proc.poll() is not None:  # (re)start outside the call's time
            if self.proc is not None:
                self.stop()
                self.restarts += 1
            self.start()
        rep = self.request({"case": case, "subs": subs}, timeout=time_limit)
        if rep is None:
            self.stop()
            self.restarts += 1
            return dict(outcome="timeout", type="Timeout", message=f"no answer within {time_limit:g} s")
        if rep.get("outcome") == "eof":
            rc = self.proc.wait()
            tail = self.log.read_text(errors="replace")[-1500:]
            self.stop()
            self.restarts += 1
            return dict(outcome="crash", type=f"exit {rc}", message="the child died (memory limit, signal)",
                        traceback=tail)
        return rep


def _last_line(tb: str) -> str:
    """The innermost ``File ..., line N, in f`` of a traceback, with its code line."""
    lines = (tb or "").splitlines()
    for i in range(len(lines) - 1, -1, -1):
        if lines[i].lstrip().startswith("File "):
            code = lines[i + 1].strip() if i + 1 < len(lines) else ""
            return f"{lines[i].strip()}: {code}"
    return ""


def run(module: str, log_dir: str | None = None, times: dict | None = None) -> tuple[list[str], int]:
    """Run every call of ``module``'s cases; return (failure lines, number of calls).

    ``times``, when given, receives the seconds spent per case (to keep the default run modest)."""
    import time

    cases = {c.name: c for c in importlib.import_module(module).CASES}
    child = _Child(module, log_dir)
    failures = []
    calls = plan(list(cases.values()))
    dead: dict[str, int] = {}  # case -> timeouts and crashes so far (each costs a restart of the child)
    try:
        for name, subs in calls:
            if dead.get(name, 0) >= MAX_DEAD:
                continue
            t0 = time.monotonic()
            rep = child.call(name, [list(s) for s in subs], cases[name].time_limit)
            if times is not None:
                times[name] = times.get(name, 0.0) + time.monotonic() - t0
            # the valid call must return (else only error paths are fuzzed); a hostile one may raise
            if rep["outcome"] == "ok" or (subs and rep["outcome"] == "repro_error"):
                continue
            if rep["outcome"] in ("timeout", "crash"):
                dead[name] = dead.get(name, 0) + 1
                if dead[name] == MAX_DEAD:
                    failures.append(f"{name}: stopped after {MAX_DEAD} timeouts/crashes (its other calls not run)")
            what = ", ".join(f"{p}={lab}" for p, lab in subs) or "(valid arguments)"
            failures.append(f"{name}({what}): {rep['outcome']} {rep.get('type', '')}: "
                            f"{(rep.get('message') or '').splitlines()[0][:200] if rep.get('message') else ''}"
                            + (f"\n    at {_last_line(rep.get('traceback', ''))}" if rep.get("traceback") else ""))
    finally:
        child.stop()
    return failures, len(calls)


def check(module: str, log_dir: str | None = None) -> None:
    """The pytest entry: fail listing every bad valid call and every failing hostile call of ``module``."""
    failures, n = run(module, log_dir)
    if failures:
        raise AssertionError(f"{len(failures)} of {n} calls failed the outcome rule "
                             f"(ReproError or a finite result):\n" + "\n".join(failures))


def main(argv: list[str]) -> None:
    if argv[:1] == ["--child"]:
        child_main(argv[1])
    elif argv[:1] == ["--run"]:
        times: dict = {}
        failures, n = run(argv[1], times=times)
        print("\n".join(failures) or "no failure", f"\n({len(failures)} failures of {n} calls)")
        slow = sorted(times.items(), key=lambda kv: -kv[1])[:10]
        print("slowest cases:", ", ".join(f"{k} {v:.1f} s" for k, v in slow))
    else:
        print(__doc__)


if __name__ == "__main__":
    main(sys.argv[1:])
