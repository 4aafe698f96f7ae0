"""Whole-command fuzzing of the CLI (issues 16 and 29): every command run on mutated inputs
and flags, each in its own process with a time bound.

Every run is one whole command, ``arfem.scenarios.cli.main(argv)`` exactly as
``python -m arfem`` runs it, in a child process forked from a parent that has imported
arfem once (so a run costs its work, not 2 s of imports), with its stdin, stdout and
stderr in files, killed at the bound. Commands and what is mutated:

- ``compensate``: ``model.json`` (a key's value replaced by a wrong type, NaN/inf, a
  negative, 1e-320 or 1e308, a list, null, a boolean; a key deleted or added; a matrix
  reshaped), the record's CSV (a cell replaced) and the flags (``--max-offset-um``,
  ``--max-step-um``, ``--probe-every``, ``--score-from``);
- ``compensate --live`` (JSON lines): ``CONFIG.toml`` values and the input lines;
- ``run`` and ``check``: a value of a small scenario TOML, and the flags of ``check``;
- ``sweep``: a value of a 2-point sweep TOML and the flags;
- ``diagnose``: a value of the dataset TOML or a cell of its CSV, ``--holdout-start``;
- ``allocate``: a value of a small allocation TOML (50 generations), ``--seeds``;
- ``report``: folders arfem did or did not write, with and without a user's
  ``report.html``, a deleted or corrupted manifest, a missing folder, a file;
- ``twin``: every flag (2 intervals at 10 ms, port 0);
- ``reproduce``: an ``--out`` that is a file, a user's folder, a check;
- ``meshrun`` (issue 41): ``arfem run`` on a mesh scenario (the box of
  ``tests/geometry_meshes.py``): a value of its TOML, or its ``.msh`` (text meshio
  cannot parse, cut short, a node at 1e308);
- ``meshrec`` (issue 41): a mesh run's contract-v3 record (the coarse spindle unit's,
  1441 rows), a cell or the header of its CSV or a value of its TOML, replayed by
  ``arfem compensate`` (and, one run in six, diagnosed by ``arfem diagnose``).

Counted and printed (targets: all 0):

- tracebacks: an exit status other than 0, 2 or 130 (or 1 where documented: a failed
  ``check``, a failed sweep point), or a Python traceback on stderr;
- hangs: killed at the bound;
- not one line: exit 2 with other than exactly one ``arfem: error:`` line;
- non-finite results of an exit 0: ``NaN``/``Infinity`` tokens in a JSON file written,
  ``nan``/``inf`` cells in a CSV file written (except in columns that echo the record's
  readings -- a reading the record lacks stays missing -- and, in ``compensated.csv``,
  except a held cycle's prediction: there only ``offset_um``, the number sent to the
  machine, is checked), or a ``nan``/``inf`` number on stdout;
- user files changed: an input file or a user's ``report.html`` whose bytes changed.

Issue 16's parts run on request: ``--hypothesis N`` (tests/test_fuzz.py with N examples per
test, the ``fuzz`` profile) and ``--hangs`` (extreme ``arfem sweep`` invocations as
subprocesses: ``--workers 100000``, ``--connect-timeout 1e308`` against a closed port, a
Dask scheduler without a worker, a 100³ grid).

Run:  nice -n 10 python benchmarks/fuzz_cli.py [--runs 1100] [--jobs 2] [--seed 1]
          [--hypothesis 500] [--hangs]
"""
from __future__ import annotations

import argparse
import copy
import json
import os
import random
import re
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from collections import Counter, defaultdict
from pathlib import Path

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")           # no BLAS threads across fork()
os.environ.setdefault("MPLBACKEND", "Agg")

ROOT = Path(__file__).resolve().parents[1]
FL = ROOT / "scenarios" / "data" / "fl_thermal"

BASE = """[scenario]
name = "coarse"
[cycle]
phases = [
  { duration_h = 2.0,  q_W_m2 = 2000.0 },
  { duration_h = 1.0,  q_W_m2 = 0.0 },
  { duration_h = 2.0,  q_W_m2 = 3000.0 },
  { duration_h = 5.0,  q_W_m2 = 0.0 },
]
[rod]
convection_W_m2K = 55.0
[ar]
dtau_s = 300.0
[fem]
model = "axisymmetric"
[fem.mesh]
nr = 3
nz = 10
"""
SWEEP = ('[sweep]\nname = "fz"\nbase = "base.toml"\n[sweep.grid]\n'
         'dtau_s = [300, 600]\nh_W_m2K = [55]\n')
LIVE = '[live]\ntransport = "jsonl"\nmax_offset_um = 50.0\nmax_step_um = 5.0\ncycles = 0\n'
#: weird values: TOML literals, JSON values, CSV cells, flag strings
WEIRD_TOML = ["nan", "inf", "-inf", "-1", "0", "1e-320", "1e308", "-1e308", '"x"', '""',
              "[]", "[1]", "{ a = 1 }", "true", "9223372036854775807", "1e400", "0.0",
              "-0.0", "2.5", '"1h"', "[nan]", "[1e308, 1e308]"]
WEIRD_JSON = [float("nan"), float("inf"), float("-inf"), -1, 0, 1e-320, 1e308, -1e308, "x",
              "", [], [1], [[1, 2]], {}, None, True, False, 10 ** 30, [[float("nan")]],
              [[1e308]], {"x": [1], "y": [1]}, 0.5, [0.5], "nan"]
WEIRD_CELL = ["nan", "inf", "-inf", "", "x", "1e400", "-1e308", "1e-320", "0", "-1",
              "1,2", '"', "NaN", "9" * 400]
WEIRD_FLAG = ["nan", "inf", "-inf", "-1", "0", "1e-320", "1e308", "-1e308", "x", "",
              "1e400", "2", "0.5", "100000", "-0", "1h", "0s", "1e9h", "-5min", "3"]
TOKEN = re.compile(r'(?P<k>[A-Za-z_][\w."]*)\s*=\s*(?P<v>\[[^\]\n]*\]|"[^"\n]*"|[^,\s}\]\n]+)')
NONFINITE_OUT = re.compile(r"(?<![\w.])[-+]?(nan|inf|infinity)(?![\w])", re.I)


# -- inputs ----------------------------------------------------------------------------

def make_inputs(d: Path) -> dict:
    """Valid inputs of every command, written into ``d``; returns their paths/texts."""
    from arfem.api import Rod, ar1, ar1_model, paper_cycle
    from arfem.models.diagnosis.synth import generate
    from arfem.scenarios.compensation.model_file import write_model
    from arfem.scenarios.records.synth_files import write_case
    (d / "base.toml").write_text(BASE, "utf-8")
    (d / "sw.toml").write_text(SWEEP, "utf-8")
    with open(FL / "fl_thermal_whole.csv", encoding="utf-8") as fh:
        (d / "fl_thermal_whole.csv").write_text("".join(next(fh) for _ in range(801)), "utf-8")
    (d / "case.toml").write_text((FL / "fl_thermal_ch1.toml").read_text("utf-8"), "utf-8")
    a = ar1(Rod(), paper_cycle(2000.0), dtau_s=60.0)
    model = ar1_model(a.C1, a.C2_um_per_W_m2, dtau_s=60.0, Q_um2=0.01, R_um2=0.01)
    write_model(d / "model.json", model)
    case = generate("none", 29, duration_h=6.0, interval_s=60, jitter_s=0.0, n_gaps=0,
                    empty_fraction=0.0, n_outliers=0)
    rec = write_case(case, d / "rec")
    alloc = (ROOT / "scenarios" / "data" / "pallet_changer.toml").read_text("utf-8")
    alloc = re.sub(r"n_gen\s*=\s*\d+", "n_gen = 50", alloc)
    if "n_gen" not in alloc:
        alloc = alloc.replace("[optimizer]", "[optimizer]\nn_gen = 50") if "[optimizer]" \
            in alloc else alloc + "\n[optimizer]\nn_gen = 50\npop_size = 20\n"
    (d / "alloc.toml").write_text(alloc, "utf-8")
    (d / "live.toml").write_text(LIVE, "utf-8")
    mesh = make_mesh_inputs(d)
    return {**mesh, "model": json.loads((d / "model.json").read_text("utf-8")), "record": rec,
            "record_csv": rec.with_suffix(".csv").read_text("utf-8"),
            "base": BASE, "sweep": SWEEP, "alloc": alloc, "live": LIVE,
            "case_toml": (d / "case.toml").read_text("utf-8"),
            "case_csv": (d / "fl_thermal_whole.csv").read_text("utf-8")}


def make_mesh_inputs(d: Path) -> dict:
    """The box scenario and its mesh (``meshrun``), and a mesh run's v3 record with its
    scenario, mesh and model.json (``meshrec``), written into ``d``."""
    import importlib.util
    spec = importlib.util.spec_from_file_location("geometry_meshes",
                                                  ROOT / "tests" / "geometry_meshes.py")
    gm = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(gm)
    BOX_TOML, box_meshio, write_msh = gm.BOX_TOML, gm.box_meshio, gm.write_msh
    from arfem.scenarios.cli import main as cli_main
    write_msh(box_meshio(), d / "box.msh")
    geo = ROOT / "tests" / "data" / "geodiag"
    (d / "unit").mkdir()
    shutil.copy(geo / "spindle_coarse.msh", d / "unit")
    (d / "unit" / "unit.toml").write_text(
        (geo / "spindle_coarse.toml").read_text("utf-8").replace("picture = true",
                                                                 "picture = false"), "utf-8")
    rc = cli_main(["run", str(d / "unit" / "unit.toml"), "--out", str(d / "unit" / "run"),
                   "--no-progress"])
    assert rc == 0, "the mesh run of the fuzz's inputs failed"
    r = d / "unit" / "run"
    return {"box": BOX_TOML, "box_msh": (d / "box.msh").read_text("utf-8"),
            "v3_toml": (r / "record.toml").read_text("utf-8"),
            "v3_csv": (r / "record.csv").read_text("utf-8"),
            "v3_files": {n: (r / n).read_bytes() for n in ("scenario.toml",
                                                          "spindle_coarse.msh", "model.json")}}


def mutate_msh(text: str, rng: random.Random) -> str:
    """A mesh file meshio cannot parse, cut short, or with a node far away."""
    op = rng.random()
    if op < 0.3:
        return rng.choice(["hello\n", "", "$MeshFormat\n9.9 0 8\n$EndMeshFormat\n"])
    if op < 0.5:
        return text[:rng.randrange(len(text))]
    lines = text.splitlines()
    i = lines.index("$Nodes") + 2 + rng.randrange(10)
    parts = lines[i].split()
    parts[1 + rng.randrange(3)] = rng.choice(["1e308", "-1e308", "nan", "inf", "1e6", "x"])
    lines[i] = " ".join(parts)
    return "\n".join(lines) + "\n"


def mutate_toml(text: str, rng: random.Random) -> str:
    ms = list(TOKEN.finditer(text))
    m = rng.choice(ms)
    op = rng.random()
    if op < 0.85:
        new = rng.choice(WEIRD_TOML)
        return text[:m.start("v")] + new + text[m.end("v"):]
    if op < 0.95:                                      # delete the pair's line
        a = text.rfind("\n", 0, m.start()) + 1
        b = text.find("\n", m.end())
        return text[:a] + text[b + 1 if b >= 0 else len(text):]
    return text + f"\n{rng.choice(['zzz', 'typo_key'])} = 1\n"


def mutate_json(doc, rng: random.Random):
    doc = copy.deepcopy(doc)
    paths = []

    def walk(o, path):
        paths.append(path)
        if isinstance(o, dict):
            for k, v in o.items():
                walk(v, path + [k])
        elif isinstance(o, list):
            for i, v in enumerate(o):
                walk(v, path + [i])
    walk(doc, [])
    path = rng.choice(paths[1:])
    parent = doc
    for p in path[:-1]:
        parent = parent[p]
    op = rng.random()
    if op < 0.8:
        parent[path[-1]] = rng.choice(WEIRD_JSON)
    elif op < 0.9 and isinstance(parent, dict):
        del parent[path[-1]]
    elif isinstance(parent, list):
        parent.append(copy.deepcopy(parent[path[-1]]))
    else:
        doc[rng.choice(["gain", "Q", "noise2"])] = 1
    return doc


def mutate_csv(text: str, rng: random.Random) -> str:
    lines = text.splitlines()
    op = rng.random()
    if op < 0.8:
        i = rng.randrange(1, len(lines))
        cells = lines[i].split(",")
        j = rng.randrange(len(cells))
        cells[j] = rng.choice(WEIRD_CELL)
        lines[i] = ",".join(cells)
    elif op < 0.9:
        i = rng.randrange(1, len(lines) - 1)
        lines[i], lines[i + 1] = lines[i + 1], lines[i]          # time goes back
    else:
        hdr = lines[0].split(",")
        hdr[rng.randrange(len(hdr))] = rng.choice(["", "time_s", "x", "growth_um"])
        lines[0] = ",".join(hdr)
    return "\n".join(lines) + "\n"


def weird_flag(rng):
    return rng.choice(WEIRD_FLAG)


# -- cases -------------------------------------------------------------------------------

def case_for(cmd: str, i: int, d: Path, inp: dict, rng: random.Random) -> dict:
    """One run: argv, files to write first, stdin text, protected files."""
    w = d / f"c{i:05d}"
    w.mkdir()
    files, stdin, protect = {}, "", []
    out = w / "out"
    if cmd == "compensate":
        model = inp["model"]
        rec_csv = inp["record_csv"]
        r = rng.random()
        if r < 0.6:
            model = mutate_json(model, rng)
        elif r < 0.75:
            rec_csv = mutate_csv(rec_csv, rng)
        files["model.json"] = json.dumps(model, allow_nan=True)
        rec_toml = inp["record"].read_text("utf-8")
        files[inp["record"].name] = rec_toml
        files[inp["record"].with_suffix(".csv").name] = rec_csv
        argv = ["compensate", str(w / "model.json"), str(w / inp["record"].name),
                "--out", str(out)]
        for flag in ("--max-offset-um", "--max-step-um", "--probe-every", "--score-from"):
            if r >= 0.75 and rng.random() < 0.5:
                argv += [flag, weird_flag(rng)]
            elif flag == "--probe-every" and rng.random() < 0.3:
                argv += [flag, "1h"]
        protect = list(files)
    elif cmd == "live":
        model = inp["model"] if rng.random() < 0.7 else mutate_json(inp["model"], rng)
        files["model.json"] = json.dumps(model, allow_nan=True)
        files["live.toml"] = inp["live"] if rng.random() < 0.4 else mutate_toml(inp["live"], rng)
        lines = []
        for k in range(rng.randrange(1, 8)):
            v = rng.choice([2000.0, 0.0, 3000.0, "nan", None, "x", 1e308, -1, "inf"])
            row = {"time_s": 60.0 * (k + 1), "q_W_m2": v}
            if rng.random() < 0.1:
                row = rng.choice([[1], "x", {"time_s": "x"}, {}])
            lines.append(json.dumps(row) if not (isinstance(v, str) and v in ("nan", "inf"))
                         else f'{{"time_s": {60.0 * (k + 1)}, "q_W_m2": {v.capitalize() if v == "nan" else "Infinity"}}}')
        if rng.random() < 0.1:
            lines.append("{not json")
        stdin = "\n".join(lines) + "\n"
        argv = ["compensate", str(w / "model.json"), "--live", str(w / "live.toml")]
        protect = list(files)
    elif cmd in ("run", "check"):
        files["s.toml"] = mutate_toml(inp["base"], rng) if rng.random() < 0.85 else inp["base"]
        if cmd == "run":
            argv = ["run", str(w / "s.toml"), "--out", str(out)]
        else:
            argv = ["check", str(w / "s.toml")]
            for flag in ("--max-abs-pct", "--max-c1-diff"):
                if rng.random() < 0.4:
                    argv += [flag, weird_flag(rng)]
            if rng.random() < 0.2:
                argv += ["--json", str(w / "check.json")]
        protect = list(files)
    elif cmd == "sweep":
        files["base.toml"] = inp["base"]
        files["sw.toml"] = mutate_toml(inp["sweep"], rng) if rng.random() < 0.7 else inp["sweep"]
        if rng.random() < 0.2:
            files["base.toml"] = mutate_toml(inp["base"], rng)
        argv = ["sweep", str(w / "sw.toml"), "--out", str(out), "--no-progress"]
        if rng.random() < 0.4:
            flag = rng.choice(["--workers", "--connect-timeout", "--worker-wait",
                               "--max-points"])
            argv += [flag, weird_flag(rng)]
        else:
            argv += ["--workers", "1"]
        protect = list(files)
    elif cmd == "diagnose":
        ct, cc = inp["case_toml"], inp["case_csv"]
        r = rng.random()
        if r < 0.45:
            ct = mutate_toml(ct, rng)
        elif r < 0.85:
            cc = mutate_csv(cc, rng)
        files["case.toml"], files["fl_thermal_whole.csv"] = ct, cc
        argv = ["diagnose", str(w / "case.toml"), "--out", str(out)]
        if r >= 0.85:
            argv += ["--holdout-start", weird_flag(rng)]
        protect = list(files)
    elif cmd == "meshrun":
        files["box.toml"] = mutate_toml(inp["box"], rng) if rng.random() < 0.85 else inp["box"]
        files["box.msh"] = (mutate_msh(inp["box_msh"], rng) if rng.random() < 0.15
                            else inp["box_msh"])
        argv = ["run", str(w / "box.toml"), "--out", str(out), "--no-progress"]
        protect = list(files)
    elif cmd == "meshrec":
        ct, cc = inp["v3_toml"], inp["v3_csv"]
        r = rng.random()
        if r < 0.2:
            ct = mutate_toml(ct, rng)
        else:
            cc = mutate_csv(cc, rng)
        files["record.toml"], files["record.csv"] = ct, cc
        for name, data in inp["v3_files"].items():
            (w / name).write_bytes(data)
        if rng.random() < 1 / 6:
            argv = ["diagnose", str(w / "record.toml"), "--out", str(out), "--no-progress"]
        else:
            argv = ["compensate", str(w / "model.json"), str(w / "record.toml"),
                    "--out", str(out)]
        protect = list(files)
    elif cmd == "allocate":
        files["a.toml"] = mutate_toml(inp["alloc"], rng) if rng.random() < 0.85 else inp["alloc"]
        argv = ["allocate", str(w / "a.toml"), "--out", str(out)]
        if rng.random() < 0.2:
            argv += ["--seeds", rng.choice(["0", "-1", "1", "101", "x", "2"])]
        protect = list(files)
    elif cmd == "report":
        kind = rng.choice(["foreign", "foreign_user_report", "no_manifest", "manifest_no_report",
                           "corrupt_manifest", "arfem", "arfem_user_edit", "missing", "file",
                           "arfem_report_dir"])
        out.mkdir()
        (out / "summary.json").write_text('{"rmse_um": 0.25, "x": [1, 2]}', "utf-8")
        if kind.startswith("arfem") or kind in ("no_manifest", "manifest_no_report",
                                                "corrupt_manifest"):
            from arfem.scenarios.outdir import adopt_outputs
            (out / "report.html").write_text("<p>arfem's</p>", "utf-8")
            adopt_outputs(out, ["summary.json", "report.html"])
        if kind == "no_manifest":
            (out / ".arfem-outputs.json").unlink()
            (out / "report.html").write_text("<p>user's own</p>", "utf-8")
        elif kind == "manifest_no_report":
            from arfem.scenarios.outdir import OWNERSHIP_MANIFEST
            man = json.loads((out / OWNERSHIP_MANIFEST).read_text("utf-8"))
            del man["files"]["report.html"]
            (out / OWNERSHIP_MANIFEST).write_text(json.dumps(man), "utf-8")
            (out / "report.html").write_text("<p>user's own</p>", "utf-8")
        elif kind == "corrupt_manifest":
            (out / ".arfem-outputs.json").write_text(rng.choice(["{", "[]", '{"files": 3}',
                                                                 "null"]), "utf-8")
            (out / "report.html").write_text("<p>user's own</p>", "utf-8")
        elif kind == "foreign_user_report":
            (out / "report.html").write_text("<p>user's own</p>", "utf-8")
        elif kind == "arfem_user_edit":
            (out / "report.html").write_text("<p>edited by the user</p>", "utf-8")
        elif kind == "arfem_report_dir":
            (out / "report.html").unlink()
            (out / "report.html").mkdir()
        target = out
        if kind == "missing":
            target = w / "nope"
        elif kind == "file":
            target = out / "summary.json"
        argv = ["report", str(target)] + (["--force"] if rng.random() < 0.2 else [])
        if (out / "report.html").is_file() and "user" in (out / "report.html").read_text():
            if "edited" not in (out / "report.html").read_text() or "--force" not in argv:
                protect.append(str((out / "report.html").relative_to(w)))
    elif cmd == "twin":
        argv = ["twin", "--port", "0", "--steps", "2", "--period-s", "0.01",
                "--record", str(w / "rec")]
        for flag in ("--dtau-s", "--ambient-amplitude-K", "--noise-um", "--seed", "--start-h",
                     "--nan-at-step", "--period-s", "--steps", "--port"):
            if rng.random() < 0.25:
                argv += [flag, weird_flag(rng)]
    elif cmd == "reproduce":
        kind = rng.choice(["file", "user", "check_file"])
        if kind == "file":
            (w / "f").write_text("x")
            argv = ["reproduce", "--out", str(w / "f")]
            protect = ["f"]
        elif kind == "user":
            out.mkdir()
            (out / "notes.txt").write_text("mine")
            argv = ["reproduce", "--out", str(out)]
            protect = ["out/notes.txt"]
        else:
            (w / "f").write_text("x")
            argv = ["reproduce", "--check", "--out", str(w / "f" / "sub")]
    else:
        raise ValueError(cmd)
    for name, text in files.items():
        (w / name).parent.mkdir(parents=True, exist_ok=True)
        (w / name).write_text(text, "utf-8")
    return {"cmd": cmd, "argv": [str(a) for a in argv], "dir": w, "stdin": stdin,
            "protect": {p: (w / p).read_bytes() for p in protect}}


# -- running one case in a forked child -----------------------------------------------------

def start(case: dict) -> int:
    w = case["dir"]
    (w / "stdin.txt").write_text(case["stdin"], "utf-8")
    pid = os.fork()
    if pid == 0:                                           # child: the whole command
        try:
            os.setsid()
            os.chdir(w)
            fi = os.open(w / "stdin.txt", os.O_RDONLY)
            fo = os.open(w / "stdout.txt", os.O_WRONLY | os.O_CREAT | os.O_TRUNC)
            fe = os.open(w / "stderr.txt", os.O_WRONLY | os.O_CREAT | os.O_TRUNC)
            os.dup2(fi, 0)
            os.dup2(fo, 1)
            os.dup2(fe, 2)
            sys.stdin = open(0, encoding="utf-8", closefd=False)
            sys.stdout = open(1, "w", encoding="utf-8", closefd=False, buffering=1)
            sys.stderr = open(2, "w", encoding="utf-8", closefd=False, buffering=1)
            signal.signal(signal.SIGINT, signal.default_int_handler)
            from arfem.scenarios.cli import main
            try:
                rc = main(case["argv"])
            except SystemExit as e:
                rc = e.code if isinstance(e.code, int) else (0 if e.code is None else 1)
            except BaseException:                          # what python -m arfem would print
                import traceback
                traceback.print_exc()
                rc = 1
            sys.stdout.flush()
            sys.stderr.flush()
            os._exit(int(rc))
        except BaseException:
            os._exit(99)
    return pid


def judge(case: dict, rc, hung: bool) -> list[str]:
    """What is wrong with a finished run (empty: nothing)."""
    w = case["dir"]
    err = (w / "stderr.txt").read_text("utf-8", errors="replace")
    out = (w / "stdout.txt").read_text("utf-8", errors="replace")
    probs = []
    if hung:
        return ["hang"]
    # exit 1 is documented for ``check`` (a check failed) and ``sweep`` (a point failed);
    # anything else but 0, 2, 130 -- or any Python traceback -- is a crash
    legit1 = rc == 1 and case["cmd"] in ("check", "sweep")
    if (rc not in (0, 2, 130) and not legit1) or "Traceback (most recent call last)" in err:
        tail = [ln for ln in err.splitlines() if ln.strip()][-1:] or [""]
        probs.append(f"traceback: exit {rc}: {tail[0][:160]}")
    if rc == 2:
        lines = [ln for ln in err.splitlines() if ln.strip()]
        errs = [ln for ln in lines if ln.startswith("arfem: error:")]
        if len(errs) != 1:
            probs.append(f"not one line: {len(errs)} error lines of {len(lines)}: "
                         f"{(lines[-1] if lines else '')[:120]}")
    if rc == 0:
        bad = nonfinite(case, out)
        if bad:
            probs.append(f"non-finite result: {bad}")
    for rel, before in case["protect"].items():
        p = w / rel
        if not p.is_file() or p.read_bytes() != before:
            probs.append(f"user file changed: {rel}")
    return probs


def nonfinite(case: dict, stdout: str) -> str | None:
    w = case["dir"]
    cmd = case["cmd"]
    if cmd != "live":
        m = NONFINITE_OUT.search(stdout)
        if m:
            return f"stdout: ...{stdout[max(0, m.start() - 60):m.end() + 10]!r}"
    else:
        for ln in stdout.splitlines():
            try:
                o = json.loads(ln, parse_constant=lambda t: "NONFINITE")
            except ValueError:
                continue
            if isinstance(o, dict) and o.get("offset_um") == "NONFINITE":
                return f"live offset: {ln[:100]}"
    # columns of the case's own CSV files (the record): an output that echoes a reading
    # the record lacks (an empty cell) may hold NaN there; a number arfem computed may not
    echoed = set()
    for p in w.glob("**/*.csv"):
        if p.parent == w or p.parent.name == "rec":
            with open(p, encoding="utf-8", errors="replace") as fh:
                echoed |= {c.strip() for c in fh.readline().split(",")}
    for p in w.rglob("*"):
        if not p.is_file() or p.name in ("stdout.txt", "stderr.txt", "stdin.txt") \
                or p.relative_to(w).as_posix() in case["protect"] or p.name == "model.json" \
                and p.parent == w:
            continue
        if any(part.startswith(".arfem-staging") for part in p.parts):
            continue
        if p.suffix == ".json" and p.stat().st_size < 5_000_000:
            try:
                json.loads(p.read_text("utf-8"), parse_constant=_raise)
            except _NonFinite as e:
                return f"{p.relative_to(w)}: {e}"
            except ValueError:
                pass
        elif p.suffix == ".csv" and p.stat().st_size < 20_000_000 and p.parent != w:
            lines = p.read_text("utf-8", errors="replace").splitlines()
            hdr = lines[0].split(",") if lines else []
            # compensated.csv echoes the record's inputs (a missing reading stays missing)
            # and marks a held cycle's prediction NaN (docs/commands/compensate); the
            # number sent to the machine, offset_um, must always be finite
            # (per axis offset_<A>_um for a version-2 model on a v3 record)
            offs = [j for j, h in enumerate(hdr) if re.match(r"^offset(_[A-Za-z]+)?_um$", h)]
            cols = (offs if p.name == "compensated.csv" and offs else
                    [j for j, h in enumerate(hdr) if h not in echoed
                     and h not in ("growth_um", "q_W_m2", "speed_rpm", "ambient_C")
                     and not re.match(r"^T_.+_C$", h)])
            for k, ln in enumerate(lines):
                cells = ln.split(",")
                for c in (cells if cols is None else [cells[j] for j in cols if j < len(cells)]):
                    if c.strip().lower() in ("nan", "inf", "-inf", "+inf", "infinity",
                                             "-infinity"):
                        return f"{p.relative_to(w)} line {k + 1}: {c}"
    return None


class _NonFinite(ValueError):
    pass


def _raise(tok):
    raise _NonFinite(f"holds {tok}")


# -- issue 16's parts (optional: --hypothesis, --hangs) -------------------------------------

#: the coarse base scenario of the sweep tests (tests/sweep_fakes.py, which test_fuzz.py
#: imports), read as text: a module-level read failed once that file moved
HYP_BASE = (ROOT / "tests" / "sweep_fakes.py").read_text("utf-8").split('BASE = """', 1)[1] \
    .split('"""', 1)[0]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def arfem(*argv, timeout: float) -> tuple[int | None, float, str]:
    """(exit status or None if killed at ``timeout``, wall time [s], last stderr line)."""
    t0 = time.perf_counter()
    try:
        p = subprocess.run([sys.executable, "-m", "arfem", *map(str, argv)], capture_output=True,
                           text=True, timeout=timeout, cwd=tempfile.gettempdir())
        rc, err = p.returncode, p.stderr
    except subprocess.TimeoutExpired as exc:
        rc, err = None, (exc.stderr or b"").decode(errors="replace")
    lines = [ln for ln in err.splitlines() if ln.strip()]
    return rc, time.perf_counter() - t0, (lines[-1] if lines else "")[:150]


def hypothesis_part(examples: int) -> int:
    """Issue 16's part: tests/test_fuzz.py under the ``fuzz`` profile."""
    env = dict(os.environ, ARFEM_FUZZ_PROFILE="fuzz", ARFEM_FUZZ_EXAMPLES=str(examples))
    t0 = time.perf_counter()
    p = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                        "--hypothesis-show-statistics", str(ROOT / "tests" / "test_fuzz.py")],
                       capture_output=True, text=True, cwd=ROOT, env=env)
    wall = time.perf_counter() - t0
    print(f"1. property-based fuzzing (profile 'fuzz', up to {examples} examples per test)")
    name = None
    total = 0
    for ln in p.stdout.splitlines():
        m = re.match(r".*::(test_\w+)", ln)
        if m:
            name = m.group(1)
        m = re.search(r"- (\d+) passing(?: examples)?, (\d+) failing(?: examples)?, "
                      r"(?:and )?(\d+) invalid", ln)
        if m and name:
            total += int(m.group(1)) + int(m.group(2))
            print(f"   {name:<28} {m.group(1):>5} passing {m.group(2):>3} failing "
                  f"{m.group(3):>4} invalid")
    tail = [ln for ln in p.stdout.splitlines() if re.search(r"passed|failed", ln)]
    print(f"   {total} examples in {wall:.0f} s; pytest: {tail[-1] if tail else p.returncode}")
    if p.returncode:
        print("\n".join(p.stdout.splitlines()[-60:]))
    return p.returncode


def hang_part() -> int:
    """Issue 16's part: extreme ``arfem sweep`` invocations as subprocesses, bounded."""
    print("\n2. extreme invocations (subprocesses, killed at the bound)")
    bad = 0
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        (d / "base.toml").write_text(HYP_BASE, "utf-8")
        (d / "s.toml").write_text('[sweep]\nname = "s"\nbase = "base.toml"\n[sweep.grid]\n'
                                  'dtau_s = [300, 600]\nh_W_m2K = [20, 55, 150]\n', "utf-8")
        v = lambda a: "[" + ", ".join(str(a + i) for i in range(100)) + "]"
        (d / "big.toml").write_text('[sweep]\nname = "big"\nbase = "base.toml"\n[sweep.grid]\n'
                                    f'h_W_m2K = {v(5)}\nq_W_m2 = {v(1000)}\n'
                                    f'"fem.mesh.nz" = {v(4)}\n', "utf-8")
        port = free_port()
        cases = [("--workers 100000", 120, 0, ["--workers", 100000]),
                 ("--connect-timeout 1e308, closed port", 120, 2,
                  ["--scheduler", f"tcp://127.0.0.1:{port}", "--connect-timeout", "1e308"]),
                 ("100³ grid", 60, 2, None)]
        sched_port = free_port()
        sched = subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_scheduler",
                                  "--port", str(sched_port), "--no-dashboard"],
                                 stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            time.sleep(4)
            cases.append(("scheduler with no worker, --worker-wait 5", 90, 2,
                          ["--scheduler", f"tcp://127.0.0.1:{sched_port}", "--worker-wait", 5]))
            for i, (label, bound, want, flags) in enumerate(cases):
                out = d / f"o{i}"
                if flags is None:
                    rc, wall, err = arfem("sweep", d / "big.toml", "--out", out,
                                          "--no-progress", timeout=bound)
                else:
                    rc, wall, err = arfem("sweep", d / "s.toml", "--out", out, "--no-progress",
                                          *flags, timeout=bound)
                ok = rc == want
                bad += not ok
                print(f"   {'ok ' if ok else 'BAD'} {label:<42} exit {rc} (want {want}) "
                      f"{wall:6.1f} s (bound {bound} s)\n       {err}")
        finally:
            sched.kill()
            sched.wait()
    return bad



# -- main -----------------------------------------------------------------------------------

#: share of the runs per command (every command gets some)
WEIGHTS = {"compensate": 26, "report": 14, "run": 10, "check": 8, "diagnose": 9, "live": 8,
           "allocate": 8, "sweep": 8, "twin": 7, "reproduce": 2, "meshrun": 10,
           "meshrec": 10}
#: bound per command [s]: a run still going then counts as a hang
BOUND_S = {"compensate": 120, "live": 60, "run": 300, "check": 300, "sweep": 600,
           "diagnose": 600, "allocate": 600, "report": 60, "twin": 120, "reproduce": 60,
           "meshrun": 300, "meshrec": 600}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=1100)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--keep", action="store_true", help="keep the work folder")
    ap.add_argument("--hypothesis", type=int, metavar="N", default=0,
                    help="also run tests/test_fuzz.py with N examples per test (issue 16)")
    ap.add_argument("--hangs", action="store_true",
                    help="also run issue 16's extreme sweep invocations as subprocesses")
    args = ap.parse_args(argv)
    extra = 0
    if args.hypothesis:
        extra += hypothesis_part(args.hypothesis)
    if args.hangs:
        extra += hang_part()
    import arfem.scenarios.cli as cli                        # noqa: F401 - imported once
    for mod in ("arfem.scenarios.commands.run", "arfem.scenarios.commands.compensate", "arfem.scenarios.commands.sweep",
                "arfem.scenarios.geometry.scenario", "arfem.scenarios.diagnosis.mesh", "meshio",
                "arfem.scenarios.commands.diagnose", "arfem.scenarios.commands.allocate", "arfem.scenarios.commands.check",
                "arfem.scenarios.commands.report", "arfem.scenarios.commands.twin", "arfem.scenarios.live.jsonl",
                "matplotlib.pyplot"):
        __import__(mod)
    rng = random.Random(args.seed)
    tmp = Path(tempfile.mkdtemp(prefix="arfem-fuzz-"))
    inp = make_inputs(tmp)
    cmds = [c for c, n in WEIGHTS.items() for _ in range(n)]
    plan = [c for c in WEIGHTS] + [rng.choice(cmds) for _ in range(args.runs - len(WEIGHTS))]
    rng.shuffle(plan)
    t0 = time.perf_counter()
    running: dict = {}
    stats = defaultdict(Counter)
    problems = []
    i = 0
    print(f"load average {os.getloadavg()[0]:.2f}; {len(plan)} runs, {args.jobs} at a time; "
          f"work in {tmp}", flush=True)
    while i < len(plan) or running:
        while i < len(plan) and len(running) < args.jobs:
            case = case_for(plan[i], i, tmp, inp, rng)
            running[start(case)] = (case, time.monotonic())
            i += 1
        pid, status = os.waitpid(-1, os.WNOHANG)
        if pid == 0:
            now = time.monotonic()
            for p, (case, ts) in list(running.items()):
                if now - ts > BOUND_S[case["cmd"]]:
                    with contextlib_suppress():
                        os.killpg(p, signal.SIGKILL)
                    os.waitpid(p, 0)
                    del running[p]
                    finish(case, None, True, stats, problems)
            time.sleep(0.05)
            continue
        if pid not in running:
            continue
        case, ts = running.pop(pid)
        with contextlib_suppress():
            os.killpg(pid, signal.SIGKILL)                # a twin's or sweep's leftovers
        rc = os.waitstatus_to_exitcode(status)
        finish(case, rc, False, stats, problems)
        n = sum(c["runs"] for c in stats.values())
        if n % 100 == 0:
            print(f"   {n} runs done, {time.perf_counter() - t0:.0f} s", flush=True)
    wall = time.perf_counter() - t0
    total = Counter()
    print(f"\n{'command':<11} {'runs':>5} {'exit 0':>7} {'exit 2':>7} {'other':>6} "
          f"{'traceb.':>8} {'hangs':>6} {'!1 line':>8} {'nonfin.':>8} {'changed':>8}")
    for cmd in WEIGHTS:
        s = stats[cmd]
        total.update(s)
        print(f"{cmd:<11} {s['runs']:>5} {s['exit 0']:>7} {s['exit 2']:>7} {s['exit other']:>6} "
              f"{s['traceback']:>8} {s['hang']:>6} {s['not one line']:>8} "
              f"{s['non-finite result']:>8} {s['user file changed']:>8}")
    print(f"{'all':<11} {total['runs']:>5} {total['exit 0']:>7} {total['exit 2']:>7} "
          f"{total['exit other']:>6} {total['traceback']:>8} {total['hang']:>6} "
          f"{total['not one line']:>8} {total['non-finite result']:>8} "
          f"{total['user file changed']:>8}")
    print(f"\n{total['runs']} whole-command runs in {wall:.0f} s: {total['traceback']} tracebacks, "
          f"{total['hang']} hangs, {total['non-finite result']} exit-0 results with NaN/inf, "
          f"{total['not one line']} refusals not in one line, {total['user file changed']} "
          f"user files changed (load average now {os.getloadavg()[0]:.2f})")
    for cmd, argv_, p in problems[:60]:
        print(f"  {cmd}: {' '.join(argv_)[:200]}\n      {p}")
    if not args.keep:
        shutil.rmtree(tmp, ignore_errors=True)
    bad = total["traceback"] + total["hang"] + total["non-finite result"] + \
        total["not one line"] + total["user file changed"]
    return 1 if (bad or extra) else 0


class contextlib_suppress:
    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return exc[0] is not None and issubclass(exc[0], (ProcessLookupError, PermissionError,
                                                          ChildProcessError))


def finish(case, rc, hung, stats, problems) -> None:
    s = stats[case["cmd"]]
    s["runs"] += 1
    if hung:
        s["hang"] += 1
    elif rc in (0, 2):
        s[f"exit {rc}"] += 1
    else:
        s["exit other"] += 1
    probs = judge(case, rc, hung)
    for p in probs:
        key = p.split(":")[0]
        if key != "hang":
            s[key] += 1
        problems.append((case["cmd"], case["argv"], p))
    if not probs:
        shutil.rmtree(case["dir"], ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
