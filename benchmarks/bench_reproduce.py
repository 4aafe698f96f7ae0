"""Benchmark: `arfem reproduce` end to end (both paper scenarios, all outputs).

Target (issue 3): <= 30 s wall on the 2-core reference machine. Also prints the
accuracy targets: the paper's AR(1) within 3 % of the FEM peak and the corrected
AR(1) within 0.1 % of it.

    python benchmarks/bench_reproduce.py
"""
from __future__ import annotations

import resource
import sys
import tempfile
import time
from pathlib import Path


from arfem.scenarios.rod.outputs import reproduce


def main() -> int:
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        evs = reproduce(Path(tmp) / "paper")
        wall = time.perf_counter() - t0
        files = sum(1 for p in (Path(tmp) / "paper").rglob("*") if p.is_file())
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"arfem reproduce: {wall:.2f} s wall (target <= 30 s), {files} files, "
          f"peak RSS {peak_mb:.0f} MB")
    ok = wall <= 30.0
    for ev in evs:
        m = ev.metrics
        print(f"  {ev.scenario.name}: FEM {m['fem_dofs']} dofs, FEM solve {m['fem_wall_s']:.3f} s; "
              f"paper AR max diff {m['max_abs_diff_pct_of_peak']:.3f} % of peak (<= 3 %), "
              f"corrected AR {m['corrected_max_abs_diff_pct_of_peak']:.5f} % (<= 0.1 %)")
        ok &= m["max_abs_diff_pct_of_peak"] <= 3.0 and m["corrected_max_abs_diff_pct_of_peak"] <= 0.1
    print("targets met" if ok else "TARGET MISSED")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
