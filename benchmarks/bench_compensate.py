"""Speed of the compensator: one cycle in process, and a replay of a 46 h record.

Targets of issue 21: one cycle (read inputs → offset) ≤ 1 ms at the 99th percentile in
process; the replay of a whole 46 h channel ≤ 0.5 s. The record here is generated (46.3 h
at 15 s, as FL_THERMAL, but with a q_W_m2 input, because the models arfem writes today
read the heat flux); the model is the paper's AR(1) at 15 s.

    python benchmarks/bench_compensate.py
"""
from __future__ import annotations

import os
import tempfile
import time
from pathlib import Path

import numpy as np


def main() -> int:
    from arfem.api import Rod, ar1, ar1_model, paper_cycle
    from arfem.models.compensator import Compensator
    from arfem.models.diagnosis.synth import generate
    from arfem.scenarios.compensation.replay import replay
    from arfem.scenarios.records.dataset import load_dataset
    from arfem.scenarios.records.synth_files import write_case

    print(f"load average {os.getloadavg()[0]:.2f}")
    a = ar1(Rod(), paper_cycle(2000.0), dtau_s=15.0)
    model = ar1_model(a.C1, a.C2_um_per_W_m2, dtau_s=15.0)
    comp = Compensator(model, max_offset_um=50.0, max_step_um=1.0)
    q = np.random.default_rng(0).choice([0.0, 2000.0, 3000.0], 20000)
    lat = np.empty(q.size)
    for k, qk in enumerate(q):
        t0 = time.perf_counter()
        comp.step({"q_W_m2": float(qk)})
        lat[k] = time.perf_counter() - t0
    print(f"one cycle: median {np.median(lat) * 1e6:.1f} µs, p99 {np.percentile(lat, 99) * 1e6:.1f} µs, "
          f"max {lat.max() * 1e6:.1f} µs over {q.size} cycles (target p99 ≤ 1000 µs)")
    d = Path(tempfile.mkdtemp())
    case = generate("none", 46, duration_h=46.3, interval_s=15, jitter_s=0.0, n_gaps=0,
                    empty_fraction=0.0, n_outliers=0)
    ds = load_dataset(write_case(case, d))
    best = np.inf
    for _ in range(3):
        t0 = time.perf_counter()
        res = replay(model, ds, max_offset_um=50.0, max_step_um=1.0)
        best = min(best, time.perf_counter() - t0)
    s = res.summary
    print(f"replay of {s.n_cycles} cycles (46.3 h at 15 s): best of 3 {best:.3f} s "
          f"(target ≤ 0.5 s); RMS {s.rms_before_um:.3g} -> {s.rms_after_um:.3g} µm")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
