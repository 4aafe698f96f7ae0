"""Time and peak memory of every refusal of an absurd input (issue 17's fuzzing cases).

Each case runs ``python -m arfem ...`` as a subprocess; its wall time and peak resident
memory (``wait4`` rusage of that child alone) are printed beside the exit status and
the first line it printed, and compared with a baseline in the same run: the same
command on a missing file (interpreter + arfem import + argument parsing). Before the
fix these cases ran for minutes and took 3.7-12.7 GB; the target is a one-line refusal,
exit 2, within a second or two, and memory near the baseline.

    python benchmarks/bench_limits.py [--keep DIR]
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PAPER = (ROOT / "scenarios" / "data" / "paper_fig2.toml").read_text()


def scenario(extra: str) -> str:
    """The paper's Fig. 2 scenario changed by ``extra``: a key it already has is replaced
    in place, a table header it already has is skipped, anything else is appended."""
    text = PAPER
    for line in extra.strip().splitlines():
        if line.startswith("[") and f"\n{line}\n" in text:
            continue
        key = line.split("=")[0].strip() if "=" in line else None
        if key and f"\n{key} =" in text:
            start = text.index(f"\n{key} =") + 1
            end = text.index("\n", start)
            text = text[:start] + line + text[end:]
            continue
        text += "\n" + line
    return text + "\n"


def run(argv, cwd) -> tuple[int, float, float, str]:
    t0 = time.perf_counter()
    p = subprocess.Popen([sys.executable, "-m", "arfem", *argv], cwd=cwd,
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    _, status, ru = os.wait4(p.pid, 0)
    wall = time.perf_counter() - t0
    err = p.stderr.read().decode("utf-8", "replace")
    p.stdout.read()
    rc = os.waitstatus_to_exitcode(status)
    first = (err.strip().splitlines() or ["(no output)"])[0]
    if err.count("\n") > 1:
        first += f"  [+{err.count(chr(10)) - 1} more lines]"
    return rc, wall, ru.ru_maxrss / 1024.0, first


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--keep", metavar="DIR", help="build the inputs here and keep them")
    a = ap.parse_args(argv)
    d = Path(a.keep) if a.keep else Path(tempfile.mkdtemp(prefix="bench_limits-"))
    d.mkdir(parents=True, exist_ok=True)

    cases = {
        "dtau_s = 0.001": scenario("[ar]\ndtau_s = 0.001"),
        "fem.dt_s = 1e-6, backward Euler": PAPER.replace(
            'solver = "modal"', 'solver = "backward-euler"\ndt_s = 1e-6'),
        "4096 x 4096 axisymmetric mesh": scenario("[fem.mesh]\nnr = 4096\nnz = 4096"),
        "3D mesh 200/200/400": scenario(
            'model = "3d"\n[fem.mesh]\nn_core = 200\nn_ring = 200\nnz = 400'),
        "field_interval_s = 0.5, fields off": scenario(
            "fields = false\nfield_interval_s = 0.5"),
        "field_interval_s = 1e-300": scenario("field_interval_s = 1e-300"),
        "TOML nested 600 deep": "x = " + "[" * 600 + "]" * 600 + "\n",
        "integer of 5000 digits": "[ar]\ndtau_s = " + "9" * 5000 + "\n",
    }
    rows = []
    base = run(["run", str(d / "missing.toml"), "--out", str(d / "o")], d)
    rows.append(("baseline: missing scenario file", *base))
    for i, (name, text) in enumerate(cases.items()):
        p = d / f"case{i}.toml"
        p.write_text(text)
        rows.append((f"run: {name}", *run(["run", str(p), "--out", str(d / f"o{i}")], d)))

    # measured records: 1M and 10M rows, a 2 GB file of NUL bytes (sparse: no disk used)
    toml = '[dataset]\ncsv = "{}"\n'
    for n in (1_000_000, 10_000_000):
        csv = d / f"rows{n}.csv"
        if not csv.exists():
            with open(csv, "w") as fh:
                fh.write("time_s,growth_um,q_W_m2\n")
                block = "".join(f"{i},0.1,2000\n" for i in range(100_000))
                for _ in range(n // 100_000):
                    fh.write(block)
        (d / f"rows{n}.toml").write_text(toml.format(csv.name))
        rows.append((f"diagnose: {n:,} rows ({csv.stat().st_size / 1e6:.0f} MB)",
                     *run(["diagnose", str(d / f"rows{n}.toml"), "--out", str(d / "od")], d)))
    nul = d / "nul.csv"
    with open(nul, "wb") as fh:
        fh.truncate(2 * 1024 ** 3)
    (d / "nul.toml").write_text(toml.format(nul.name))
    rows.append(("diagnose: 2 GB of NUL bytes",
                 *run(["diagnose", str(d / "nul.toml"), "--out", str(d / "od")], d)))
    rows.append(("diagnose: 2 GB of NUL bytes, --allow-large",
                 *run(["diagnose", str(d / "nul.toml"), "--out", str(d / "od"),
                       "--allow-large"], d)))
    rows.append(("run: --out name of 256 characters",
                 *run(["run", "paper_fig2", "--out", str(d / ("o" * 256))], d)))

    print(f"{'case':44s} {'exit':>4s} {'wall [s]':>9s} {'peak RSS [MB]':>14s} "
          f"{'x baseline':>10s}  first line")
    for name, rc, wall, mb, first in rows:
        print(f"{name:44s} {rc:4d} {wall:9.2f} {mb:14.0f} {mb / base[2]:10.2f}  "
              f"{first[:150]}")
    bad = [r for r in rows[1:] if r[1] != 2 or "more lines" in r[4]]
    print(f"\n{len(rows) - 1} cases; {len(bad)} not refused in one line with exit 2; "
          f"slowest refusal {max(r[2] for r in rows[1:]):.2f} s, largest peak "
          f"{max(r[3] for r in rows[1:]):.0f} MB (baseline {base[2]:.0f} MB). Inputs in {d}")
    if not a.keep:
        for f in d.glob("*"):
            if f.is_file():
                f.unlink()
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
