"""Fuzzing benchmark of the CLI (issue 16): a bigger Hypothesis run than CI, then the hang
checks as subprocesses with a timeout.

Prints
1. the property-based fuzzing of tests/test_fuzz.py under the ``fuzz`` profile (10x the
   CI examples): examples run per test, failures, wall time;
2. for each extreme invocation of ``arfem sweep`` (``--workers 100000``,
   ``--connect-timeout 1e308`` against a closed port, a Dask scheduler with no worker,
   a 100³ grid): exit status, wall time against its bound, the stderr line.

Run:  python benchmarks/fuzz_cli.py [--examples N] [--skip-hypothesis] [--skip-hangs]
"""
from __future__ import annotations

import argparse
import os
import re
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
BASE = (ROOT / "tests" / "test_fuzz.py").read_text("utf-8").split('BASE = """', 1)[1] \
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
    print("\n2. extreme invocations (subprocesses, killed at the bound)")
    bad = 0
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        (d / "base.toml").write_text(BASE, "utf-8")
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


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--examples", type=int, default=500, help="examples per test (fuzz profile)")
    ap.add_argument("--skip-hypothesis", action="store_true")
    ap.add_argument("--skip-hangs", action="store_true")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    rc = 0 if args.skip_hypothesis else hypothesis_part(args.examples)
    bad = 0 if args.skip_hangs else hang_part()
    print(f"\ntotal {time.perf_counter() - t0:.0f} s; fuzz failures: {'yes' if rc else 'none'}; "
          f"bad extreme invocations: {bad}")
    return 1 if (rc or bad) else 0


if __name__ == "__main__":
    sys.exit(main())
