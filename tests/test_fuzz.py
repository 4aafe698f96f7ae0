"""Property-based fuzzing of every file arfem reads and of the ``sweep`` flags (issue 16).

The property: whatever the input, arfem either accepts it or refuses it with ONE
:class:`~arfem.params.InputError` line (which the CLI prints as ``arfem: error: ...`` with
exit status 2). Any other exception is a traceback a user would see, and fails the test;
an example that runs longer than a bound fails too (a hang).

Inputs are valid seed files (the shipped scenarios, sweep file, allocation files and a
slice of the shipped measured recording) mutated by Hypothesis: a value replaced by an
extreme or wrongly typed one (NaN, ±inf, 1e308, 5e-324, 2**63, "", a date, a table...),
a key deleted, misspelt or added, the text truncated or spliced with junk and invalid
UTF-8. The readers are called directly (they are what the CLI calls before anything is
computed); the flags go through ``arfem.scenarios.cli.main``.

Budget: the ``ci`` profile (default) runs about 300 examples in all; ``benchmarks/
fuzz_cli.py`` selects the ``fuzz`` profile (ARFEM_FUZZ_PROFILE=fuzz), 10x more.
"""
from __future__ import annotations

import contextlib
import copy
import datetime as dt
import json
import math
import os
import signal
import tomllib
from pathlib import Path
from unittest import mock

import pytest
from hypothesis import HealthCheck, event, given, settings, strategies as st

from arfem.params import InputError
from sweep_fakes import BASE       # the coarse base scenario of the sweep tests

REPO = Path(__file__).resolve().parents[1]

settings.register_profile("ci", max_examples=50, deadline=None, derandomize=True,
                          suppress_health_check=[HealthCheck.too_slow,
                                                 HealthCheck.function_scoped_fixture])
settings.register_profile("fuzz", max_examples=int(os.environ.get("ARFEM_FUZZ_EXAMPLES", 500)),
                          deadline=None,
                          suppress_health_check=[HealthCheck.too_slow,
                                                 HealthCheck.function_scoped_fixture])
settings.load_profile(os.environ.get("ARFEM_FUZZ_PROFILE", "ci"))

#: Longest any one example may take [s] before it counts as a hang.
BOUND_S = 60


@contextlib.contextmanager
def bounded(seconds: float = BOUND_S):
    """Fail (instead of hanging the suite) if the block runs longer than ``seconds``."""
    def alarm(signum, frame):
        raise TimeoutError(f"example ran longer than {seconds} s")
    old = signal.signal(signal.SIGALRM, alarm)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


def accepted_or_one_line(fn, *args):
    """The property: ``fn`` returns, or raises InputError with a one-line message."""
    with bounded():
        try:
            fn(*args)
        except InputError as exc:
            assert "\n" not in str(exc), str(exc)
            event("refused")             # --hypothesis-show-statistics: the mix of outcomes
            return "refused"
        except MemoryError:          # the CLI turns this into one line and exit 2 as well
            event("refused: memory")
            return "refused"
    event("accepted")
    return "accepted"


# -- a small TOML writer (the mutated documents must be written back as TOML) --------------

def _bare(k: str) -> str:
    ok = k and all(c.isalnum() and c.isascii() or c in "_-" for c in k)
    return k if ok else json.dumps(k)


def _value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, (dt.datetime, dt.date, dt.time)):
        return v.isoformat()
    if isinstance(v, list):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{_bare(str(k))} = {_value(x)}" for k, x in v.items()) + "}"
    return json.dumps(str(v))


def to_toml(d: dict, prefix: str = "") -> str:
    """TOML text of a dict: scalars and lists inline, sub-tables as [headers]."""
    lines, subs = [], []
    for k, v in d.items():
        if isinstance(v, dict):
            subs.append((k, v))
        else:
            lines.append(f"{_bare(str(k))} = {_value(v)}")
    out = "\n".join(lines) + ("\n" if lines else "")
    for k, v in subs:
        name = f"{prefix}.{_bare(str(k))}" if prefix else _bare(str(k))
        out += f"\n[{name}]\n" + to_toml(v, name)
    return out


# -- mutations ---------------------------------------------------------------------------

EXTREMES = st.sampled_from([
    float("nan"), float("inf"), float("-inf"), 1e308, -1e308, 5e-324, 0.0, -0.0, -1.0, 0,
    -1, 1, 2**63, -(2**63), 10**30, "", "x" * 300, "ü\u202e", "0", "1e3", True, False,
    [], [[]], [1, "a"], {}, {"a": 1}, dt.date(2021, 7, 1), dt.time(12, 0),
    dt.datetime(2021, 7, 1, 12, 0), [float("nan")], [1e308, -1e308], [0.0] * 50])
VALUES = st.one_of(EXTREMES, st.floats(allow_nan=True, allow_infinity=True),
                   st.integers(min_value=-(2**63), max_value=2**63 - 1),
                   st.text(max_size=20), st.booleans())


def _paths(d, prefix=()):
    """Every key path in a nested dict/list document."""
    if isinstance(d, dict):
        for k, v in d.items():
            yield prefix + (k,)
            yield from _paths(v, prefix + (k,))
    elif isinstance(d, list):
        for i, v in enumerate(d[:6]):
            yield prefix + (i,)
            yield from _paths(v, prefix + (i,))


def _set(doc, path, op, value):
    cur = doc
    for k in path[:-1]:
        cur = cur[k]
    last = path[-1]
    if op == "replace":
        cur[last] = value
    elif op == "delete":
        if isinstance(cur, dict):
            cur.pop(last)
        else:
            cur.pop(last)
    elif op == "misspell" and isinstance(cur, dict) and isinstance(last, str) and last:
        cur[last[:-1] + last[-1].swapcase() + "x"] = cur.pop(last)
    elif op == "add" and isinstance(cur, dict):
        cur["unexpected_key"] = value
    elif op == "add" and isinstance(cur, list):
        cur.append(value)


@st.composite
def mutated(draw, seed: dict, n_max: int = 3):
    """A deep copy of ``seed`` with 1..n_max mutations."""
    doc = json.loads(json.dumps(seed, default=str))     # deep copy, dates as strings
    for _ in range(draw(st.integers(1, n_max))):
        paths = list(_paths(doc))
        if not paths:
            break
        path = draw(st.sampled_from(paths))
        op = draw(st.sampled_from(["replace", "replace", "replace", "delete", "misspell", "add"]))
        try:
            _set(doc, path, op, copy.deepcopy(draw(VALUES)))   # constants stay constant
        except (KeyError, IndexError, TypeError):
            pass
    return doc


@st.composite
def text_damage(draw, text: str):
    """``text`` truncated, spliced with junk, or with a line dropped/duplicated."""
    op = draw(st.sampled_from(["truncate", "splice", "drop_line", "dup_line", "bytes"]))
    if op == "truncate":
        return text[:draw(st.integers(0, len(text)))].encode()
    if op == "splice":
        i = draw(st.integers(0, len(text)))
        junk = draw(st.sampled_from(["=", "[", "]]", "\"", "\\", "\x00", "[[a]]", "a = 1",
                                     "\n[sweep]\n", "= =", "\t", "'''", "#", "nan", "ü"]))
        return (text[:i] + junk + text[i:]).encode()
    lines = text.splitlines(keepends=True)
    if op in ("drop_line", "dup_line") and lines:
        i = draw(st.integers(0, len(lines) - 1))
        lines = lines[:i] + ([lines[i]] * 2 if op == "dup_line" else []) + lines[i + 1:]
        return "".join(lines).encode()
    i = draw(st.integers(0, len(text)))
    return text[:i].encode() + draw(st.sampled_from([b"\xff", b"\xc3", b"\xef\xbb\xbf",
                                                     b"\x80\x80"])) + text[i:].encode()


def _read(path: Path) -> dict:
    return tomllib.loads(path.read_text("utf-8"))


# -- scenario files ------------------------------------------------------------------------

SCENARIO_SEEDS = [REPO / "scenarios" / "data" / f"{n}.toml" for n in ("paper_fig2", "paper_fig3")]


@given(seed=st.sampled_from(SCENARIO_SEEDS), data=st.data())
def test_fuzz_scenario_file(tmp_path, seed, data):
    """Mutated scenario files: accepted or refused in one line, never a traceback."""
    from arfem.scenarios.rod.scenario import load_scenario
    p = tmp_path / "s.toml"
    if data.draw(st.booleans()):
        p.write_text(to_toml(data.draw(mutated(_read(seed)))), "utf-8")
    else:
        p.write_bytes(data.draw(text_damage(seed.read_text("utf-8"))))
    accepted_or_one_line(load_scenario, p)


# -- sweep files ---------------------------------------------------------------------------

SWEEP = {"sweep": {"name": "fz", "base": "base.toml", "description": "fuzz",
                   "grid": {"dtau_s": [300, 600], "h_W_m2K": [20, 55],
                            "q_W_m2": [2000, 3000], "fem": {"mesh": {"nz": [4, 6]}}}}}


@given(data=st.data())
def test_fuzz_sweep_file(tmp_path, data):
    """Mutated sweep files (grid values, keys, base): accepted or one line."""
    from arfem.scenarios.sweep import load_sweep
    (tmp_path / "base.toml").write_text(BASE, "utf-8")
    p = tmp_path / "sw.toml"
    if data.draw(st.integers(0, 3)):
        p.write_text(to_toml(data.draw(mutated(SWEEP))), "utf-8")
    else:
        p.write_bytes(data.draw(text_damage(to_toml(SWEEP))))
    accepted_or_one_line(load_sweep, p)


# -- measured data (dataset TOML + CSV) --------------------------------------------------------

FL = REPO / "scenarios" / "data" / "fl_thermal"


@pytest.fixture(scope="module")
def csv_head() -> str:
    """The first 400 rows of the shipped recording (100 min at 15 s)."""
    with open(FL / "fl_thermal_whole.csv", encoding="utf-8") as fh:
        return "".join(next(fh) for _ in range(401))


@given(data=st.data())
def test_fuzz_dataset_toml(tmp_path, csv_head, data):
    """Mutated dataset descriptions over a good CSV: accepted or one line."""
    from arfem.scenarios.records.dataset import load_dataset
    (tmp_path / "fl_thermal_whole.csv").write_text(csv_head, "utf-8")
    seed = FL / "fl_thermal_ch1.toml"
    p = tmp_path / "case.toml"
    if data.draw(st.integers(0, 3)):
        p.write_text(to_toml(data.draw(mutated(_read(seed)))), "utf-8")
    else:
        p.write_bytes(data.draw(text_damage(seed.read_text("utf-8"))))
    accepted_or_one_line(load_dataset, p)


CELLS = st.sampled_from(["", "nan", "NaN", "inf", "-inf", "1e308", "-1e308", "x", "1,5",
                         "0x10", "1e-400", " 3 ", "\"2\"", "--1", "1e", "∞", "0"])


@given(data=st.data())
def test_fuzz_dataset_csv(tmp_path, csv_head, data):
    """A good description over a damaged CSV (bad cells, rows cut or doubled, time going
    back, junk bytes): accepted or one line."""
    from arfem.scenarios.records.dataset import load_dataset
    import shutil
    shutil.copy(FL / "fl_thermal_ch1.toml", tmp_path / "case.toml")
    lines = csv_head.splitlines()
    how = data.draw(st.sampled_from(["cells", "cells", "rows", "text"]))
    if how == "cells":
        for _ in range(data.draw(st.integers(1, 6))):
            i = data.draw(st.integers(0, len(lines) - 1))
            cells = lines[i].split(",")
            j = data.draw(st.integers(0, len(cells) - 1))
            cells[j] = data.draw(CELLS)
            lines[i] = ",".join(cells)
        body = ("\n".join(lines) + "\n").encode()
    elif how == "rows":
        i = data.draw(st.integers(1, len(lines) - 1))
        k = data.draw(st.integers(1, 5))
        op = data.draw(st.sampled_from(["cut", "dup", "swap", "short"]))
        if op == "cut":
            lines = lines[:i] + lines[i + k:]
        elif op == "dup":
            lines = lines[:i] + [lines[i]] * k + lines[i:]
        elif op == "swap" and i + 1 < len(lines):
            lines[i], lines[i + 1] = lines[i + 1], lines[i]
        else:
            lines[i] = ",".join(lines[i].split(",")[:k])
        body = ("\n".join(lines) + "\n").encode()
    else:
        body = data.draw(text_damage(csv_head))
    (tmp_path / "fl_thermal_whole.csv").write_bytes(body)
    accepted_or_one_line(load_dataset, tmp_path / "case.toml")


# -- allocation files ----------------------------------------------------------------------

ALLOC_SEEDS = sorted((REPO / "scenarios" / "data").glob("pallet_changer*.toml"))


@given(seed=st.sampled_from(ALLOC_SEEDS), data=st.data())
def test_fuzz_allocation_file(tmp_path, seed, data):
    """Mutated allocation scenarios: accepted or one line."""
    from arfem.scenarios.allocation.file import load_allocation_scenario
    p = tmp_path / "a.toml"
    if data.draw(st.integers(0, 3)):
        p.write_text(to_toml(data.draw(mutated(_read(seed)))), "utf-8")
    else:
        p.write_bytes(data.draw(text_damage(seed.read_text("utf-8"))))
    accepted_or_one_line(load_allocation_scenario, p)


# -- the sweep flags, through the CLI -----------------------------------------------------------

NUMS = st.sampled_from(["0", "-1", "1", "2", "100000", "1e308", "inf", "-inf", "nan", "1e-300",
                        "0.5", "", "x", "9" * 40, "2**3", "1_000"])
SCHEDULERS = st.sampled_from(["inproc://x", "inproc://", "tcp://", "tcp://:0", "x", "",
                              "tcp://256.1.1.1:1", "ucx://h:1", "tls://[::1", "://",
                              "tcp://host:99999", "ws://\x00"])


@st.composite
def sweep_flags(draw):
    flags = []
    for name in ("--workers", "--connect-timeout", "--worker-wait", "--max-points"):
        if draw(st.booleans()):
            flags += [name, draw(NUMS)]
    if draw(st.integers(0, 3)) == 0:
        flags += ["--scheduler", draw(SCHEDULERS)]
    if draw(st.booleans()):
        flags.append("--force")
    if draw(st.integers(0, 5)) == 0:
        flags.append(draw(st.sampled_from(["--bogus", "-w", "--workers", "--out"])))
    return flags


@settings(max_examples=40 if settings.default.max_examples <= 50
          else settings.default.max_examples // 5)          # each example runs a sweep
@given(flags=sweep_flags())
def test_fuzz_sweep_flags(tmp_path_factory, flags):
    """Random, extreme and malformed values of every sweep flag, through the CLI: exit
    status 0 or 2 (argparse's refusals included), never a traceback, within the bound.
    Figures are skipped here (they are tested on their own) to keep examples cheap."""
    from arfem.scenarios.cli import main
    d = tmp_path_factory.mktemp("fl")
    (d / "base.toml").write_text(BASE, "utf-8")
    (d / "sw.toml").write_text('[sweep]\nname = "one"\nbase = "base.toml"\n'
                               '[sweep.grid]\nh_W_m2K = [55]\n', "utf-8")
    with mock.patch("arfem.scenarios.sweep.report.write_figures", lambda *a: []), bounded():
        try:
            rc = main(["sweep", str(d / "sw.toml"), "--out", str(d / "o"), "--no-progress",
                       *flags])
        except SystemExit as exc:        # argparse: --help or a refused flag
            rc = exc.code
    assert rc in (0, 2), (flags, rc)
