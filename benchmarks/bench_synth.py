"""Wall time and peak memory of synthetic-dataset generation (models.diagnosis.synth).

Prints, per cause, the time to generate one 72 h case (cold = first call, building the
FEM and its modes; warm = median of 3 further seeds, as in a batch) and the time to write
and re-load it. Run:  python benchmarks/bench_synth.py
(BLAS threads matter: on a loaded 2-core machine a 175x175 eigh took 1.2 s with the
default OpenBLAS threads and 7 ms with OPENBLAS_NUM_THREADS=1.)
"""
from __future__ import annotations

import resource
import tempfile
import time

import numpy as np


from arfem.scenarios.records.dataset import load_dataset
from arfem.models.diagnosis.synth import CAUSES, generate
from arfem.scenarios.records.synth_files import write_case


def main():
    print(f"{'cause':28s} {'rows':>6s} {'cold_s':>7s} {'warm_s':>7s} {'write+load_s':>12s}")
    warm_all = {}
    for cause in CAUSES:
        t0 = time.perf_counter()
        case = generate(cause, 100, duration_h=72)
        cold = time.perf_counter() - t0
        warm = []
        for seed in (101, 102, 103):
            t0 = time.perf_counter()
            generate(cause, seed, duration_h=72)
            warm.append(time.perf_counter() - t0)
        with tempfile.TemporaryDirectory() as d:
            t0 = time.perf_counter()
            load_dataset(write_case(case, d))
            io_s = time.perf_counter() - t0
        warm_all[cause] = float(np.median(warm))
        print(f"{cause:28s} {case.time_s.size:6d} {cold:7.2f} {warm_all[cause]:7.2f} {io_s:12.2f}")
    # the contract-v2 record kinds (72 h, one seed each, after the caches are warm)
    from arfem.params import Rod
    for label, cause, kw in (("two causes", "ambient_drift+sensor_drift", {}),
                             ("warm start", "convection_mismatch", {"warm_start_h": 3.0}),
                             ("coloured noise", "none", {"noise_ar1": 0.8}),
                             ("other rod", "heat_input_scale",
                              {"rod": Rod(radius_m=0.05, length_m=0.5)}),
                             ("growth in mm", "sensor_drift", {"growth_unit_factor": 1e-3})):
        t0 = time.perf_counter()
        case = generate(cause, 104, duration_h=72, **kw)
        print(f"{label:28s} {case.time_s.size:6d} {'':>7s} {time.perf_counter() - t0:7.2f}")
    lin = np.median([v for k, v in warm_all.items() if k != "nonlinear_convection"])
    print(f"nonlinear / median linear warm time: {warm_all['nonlinear_convection'] / lin:.1f}x")
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"peak RSS: {peak_mb:.0f} MB")


if __name__ == "__main__":
    main()
