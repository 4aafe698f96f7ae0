"""Diagnosis benchmark: >= 40 generated datasets (causes drawn by the data helper's
random_case, fixed seeds), diagnosed from files; prints % named correctly per cause,
false positives on clean data, parameter errors, and the wall time and peak memory of one
72 h ``diagnose``.

    python benchmarks/bench_diagnosis.py [--n 40]
"""
from __future__ import annotations

import argparse
import collections
import resource
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from models.diagnosis.engine import diagnose_file  # noqa: E402
from models.diagnosis.synth import generate, random_case, write_case  # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--n", type=int, default=40)
    a = ap.parse_args(argv)
    tmp = Path(tempfile.mkdtemp())
    hits, total = collections.Counter(), collections.Counter()
    errs = collections.defaultdict(list)
    confusion = []
    t_all = time.perf_counter()
    for seed in range(1000, 1000 + a.n):
        case = random_case(seed)
        toml = write_case(case, tmp / f"s{seed}")
        s = diagnose_file(toml).summary
        total[case.cause] += 1
        ok = s["cause"] == case.cause
        hits[case.cause] += ok
        if not ok:
            confusion.append((seed, case.cause, s["cause"]))
        if ok:
            for k, v in case.parameters.items():
                if k in s["parameters"] and v != 0:
                    errs[k].append(abs(s["parameters"][k] - v) / abs(v))
        print(f"seed {seed}: {case.cause:28s} -> {s['cause']:28s} gain {s['holdout']['gain_pct']:6.1f} %",
              flush=True)
    print(f"\n{a.n} datasets in {time.perf_counter() - t_all:.0f} s")
    print("named correctly per cause:")
    for c in sorted(total):
        print(f"  {c:28s} {hits[c]}/{total[c]} = {100 * hits[c] / total[c]:.0f} %")
    fp = total["none"] - hits["none"]
    print(f"false positives on clean data: {fp}/{total['none']}")
    print("misnamed:", confusion)
    print("relative parameter errors (median / max):")
    for k, v in errs.items():
        v = sorted(v)
        print(f"  {k:28s} {100 * v[len(v) // 2]:.1f} % / {100 * v[-1]:.1f} %  (n={len(v)})")
    case = generate("speed_dependent_convection", 7, duration_h=72.0)
    toml = write_case(case, tmp / "long")
    t0 = time.perf_counter()
    s = diagnose_file(toml).summary
    wall = time.perf_counter() - t0
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"one 72 h diagnose ({len(case.time_s)} rows): {wall:.1f} s (target <= 60 s, ratio "
          f"{wall / 60:.2f}); cause {s['cause']}; peak RSS of the process {peak:.0f} MB")


if __name__ == "__main__":
    main()
