"""Diagnosis benchmark: a balanced batch of generated datasets -- every cause of the
contract (``none`` included) ``--per-cause`` times (default 5, so 40 cases, 5 of them
clean), fixed seeds, built by the data helper's ``generate`` -- diagnosed from files;
prints % named correctly overall and per cause, false positives on clean data, parameter
errors per cause, and the wall time and peak memory of one 72 h ``diagnose``.

    python benchmarks/bench_diagnosis.py [--per-cause 5] [--jobs 2]
"""
from __future__ import annotations

import argparse
import collections
import resource
import tempfile
import time
from pathlib import Path


from arfem.scenarios.diagnose import diagnose_file
from arfem.models.diagnosis.synth import CAUSES, generate
from arfem.scenarios.synth_files import write_case


def _one(job):
    cause, seed, tmp = job
    case = generate(cause, seed)
    toml = write_case(case, Path(tmp) / f"s{seed}")
    t0 = time.perf_counter()
    s = diagnose_file(toml).summary
    return case, s, time.perf_counter() - t0


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--per-cause", type=int, default=5)
    ap.add_argument("--jobs", type=int, default=1)
    a = ap.parse_args(argv)
    tmp = Path(tempfile.mkdtemp())
    hits, total = collections.Counter(), collections.Counter()
    errs = collections.defaultdict(list)
    confusion = []
    t_all = time.perf_counter()
    jobs = [(CAUSES[i % len(CAUSES)], 1000 + i, str(tmp))
            for i in range(a.per_cause * len(CAUSES))]
    if a.jobs > 1:
        from concurrent.futures import ProcessPoolExecutor
        with ProcessPoolExecutor(a.jobs) as ex:
            results = list(ex.map(_one, jobs))
    else:
        results = map(_one, jobs)
    n = len(jobs)
    walls = []
    for (cause, seed, _), (case, s, wall) in zip(jobs, results):
        walls.append(wall)
        total[case.cause] += 1
        ok = s["cause"] == case.cause
        hits[case.cause] += ok
        if not ok:
            confusion.append((seed, case.cause, s["cause"]))
        if ok:
            for k, v in case.parameters.items():
                if k in s["parameters"] and v != 0:
                    errs[(case.cause, k)].append(abs(s["parameters"][k] - v) / abs(v))
        print(f"seed {seed}: {case.cause:28s} -> {s['cause']:28s} gain {s['holdout']['gain_pct']:6.1f} %",
              flush=True)
    print(f"\n{n} datasets in {time.perf_counter() - t_all:.0f} s wall ({a.jobs} jobs); "
          f"diagnose per case median {sorted(walls)[n // 2]:.1f} s, max {max(walls):.1f} s")
    print(f"named correctly overall: {sum(hits.values())}/{n} = "
          f"{100 * sum(hits.values()) / n:.0f} %")
    print("named correctly per cause:")
    for c in sorted(total):
        print(f"  {c:28s} {hits[c]}/{total[c]} = {100 * hits[c] / total[c]:.0f} %")
    fp = total["none"] - hits["none"]
    print(f"false positives on clean data: {fp}/{total['none']}")
    print("misnamed:", confusion)
    print("relative parameter errors where the cause was named (median / max):")
    for (c, k), v in sorted(errs.items()):
        v = sorted(v)
        print(f"  {c:28s} {k:24s} {100 * v[len(v) // 2]:.1f} % / {100 * v[-1]:.1f} %  (n={len(v)})")
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
