"""The field peers (issue 34) on generated records: compensated residual of every model.

The same records as ``bench_diagnosis.py`` (arfem's generator, ``--source inside``) or
``bench_diagnosis_outside.py`` (a 3D rod, other duty cycles and noises, ``--source
outside``), built by those scripts' own functions with the same seeds. On each record:

* ``arfem diagnose`` (default hold-out: the last third; ``intervals=False``) and the
  models it exports (``compensator_models``): the paper AR(1) of the record's ``[rod]``
  (eqs. 12-14, not fitted), the extended model where a cause is named, the MLR where the
  record has thermometers;
* the two peers of ``arfem.models.peers`` fitted on the rows before the hold-out: the
  multi-input transfer functions (heat source ``q_W_m2``; candidates ``ambient_C`` and any
  ``T_*`` column; CV selection as pre-registered for FL_THERMAL) and the SysIdentPy ARX
  (inputs q [kW/m²], ambient, thermometers; BIC), in simulation mode;
* every model replayed by the same causal ``replay`` from the first row, scored on the
  hold-out: RMS of measured growth + offset [µm].

Generated records have empty growth cells and spikes (the generator's measurement
errors): the TF fit leaves them out of its loss (the dataset's outlier flags); SysIdentPy
takes no mask, so for the ARX fit they are filled by linear interpolation. Scores count
every finite row.

Prints, per kind of record, the median RMS after compensation of each model and how often
each is best; then the totals, and how often the extended model beats the better peer.

    python benchmarks/bench_peers.py [--source inside|outside] [--per-kind 1] [--jobs 2]
                                     [--seed-start S] [--limit N]
"""
from __future__ import annotations

import argparse
import collections
import os
import tempfile
import time
import warnings
from pathlib import Path

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import numpy as np  # noqa: E402


MODELS = ("uncompensated", "ar1", "mlr", "extended", "tf", "arx")


def peers_for(ds, hs):
    """The two peers fitted on the rows before ``hs`` [s]; ({key: model}, {key: why not})."""
    from arfem import __version__
    from arfem.models.compensator import noise_var_um2
    from arfem.models.peers import (arx_state_space, fit_arx, fit_transfer_functions,
                                    tf_state_space)
    from arfem.params import InputError
    t = np.asarray(ds.time_s, float)
    g = np.asarray(ds.growth_um, float)
    first = 1 if t[0] <= 0.0 else 0
    n = int(np.searchsorted(t, hs))
    U = {"q_W_m2": np.asarray(ds.q_W_m2, float)}
    if ds.ambient_C is not None:
        U["ambient_C"] = np.asarray(ds.ambient_C, float)
    U.update({k: np.asarray(v, float) for k, v in ds.temperatures.items()})
    U = {k: v for k, v in U.items() if np.all(np.isfinite(v[:n]))}
    units = {k: ("W/m²" if k == "q_W_m2" else "°C") for k in U}
    dt = float(np.median(np.diff(t)))
    ref = {k: float(v[0]) for k, v in U.items()}
    ref["q_W_m2"] = 0.0
    rows = slice(first, n)
    fitU = {k: v[rows] for k, v in U.items()}
    bad = ~np.isfinite(g) | np.asarray(ds.outliers, bool)
    R = noise_var_um2(np.where(bad, np.nan, g)[:n])
    out, why = {}, {}
    try:
        tf = fit_transfer_functions(g[rows], fitU, units, dtau_s=dt, heat_source="q_W_m2",
                                    reference=ref, valid=~bad[rows])
        out["tf"] = tf_state_space(tf, R_um2=R, arfem_version=__version__)
    except InputError as exc:
        why["tf"] = str(exc)
    idx = np.arange(t.size)
    gi = np.interp(idx, idx[~bad], g[~bad])
    try:
        arx = fit_arx(gi[rows], fitU, units, dtau_s=dt, reference=ref,
                      scale={"q_W_m2": 1e-3})
        g0 = float(gi[first - 1]) if first else float(gi[0])
        out["arx"] = arx_state_space(arx, y_start_um=g0, Q_um2=arx.one_step_rms_um ** 2,
                                     R_um2=R, arfem_version=__version__)
    except InputError as exc:
        why["arx"] = str(exc)
    return out, why


def score_record(ds):
    """RMS after compensation [µm] of every model on the hold-out of ``ds``."""
    from arfem.models.diagnosis.engine import diagnose
    from arfem.scenarios.compensation.replay import replay
    from arfem.scenarios.diagnosis.run import compensator_models
    from arfem.params import InputError
    d = diagnose(ds, None, intervals=False)
    hs = d.holdout.start_s
    models = compensator_models(ds, hs, d)
    peers, why = peers_for(ds, hs)
    want = {"ar1": models.get("model.json"), "mlr": models.get("model_mlr.json"),
            "extended": models.get("model_extended.json"), **peers}
    t = np.asarray(ds.time_s, float)
    g = np.asarray(ds.growth_um, float)
    ok = np.isfinite(g) & (t >= hs)
    sc = {"uncompensated": float(np.sqrt(np.mean(g[ok] ** 2)))}
    for k, m in want.items():
        if m is None:
            continue
        try:
            r = replay(m, ds, score_from_s=hs).series.residual_um
        except InputError as exc:
            why[k] = str(exc)
            continue
        sc[k] = float(np.sqrt(np.mean(r[ok] ** 2)))
    return sc, d.cause, why


_MODEL = None


def _one(job):
    warnings.simplefilter("ignore")
    source, kind, label, seed, ov, tmp = job
    from arfem.scenarios.records.dataset import load_dataset
    from arfem.scenarios.records.synth_files import write_case
    c0 = time.process_time()
    if source == "inside":
        from arfem.models.diagnosis.synth import generate
        from arfem.params import Rod
        ov = dict(ov)
        rod = Rod(**ov.pop("rod")) if "rod" in ov else None
        case = generate(label, seed, rod=rod, **ov)
    else:
        global _MODEL
        from bench_diagnosis_outside import MESH, make_case

        from arfem.fem.heat import build_3d
        from arfem.params import Rod
        if _MODEL is None:
            _MODEL = build_3d(Rod(), **MESH)
        case = make_case(label, ov, seed, _MODEL)
    toml = write_case(case, Path(tmp) / f"s{seed}")
    try:
        ds = load_dataset(toml)
        sc, named, why = score_record(ds)
    except Exception as exc:            # a record the diagnosis refuses (e.g. wrong units)
        return kind, seed, {}, f"refused: {type(exc).__name__}: {exc}", {}, 0.0
    return kind, seed, sc, named, why, time.process_time() - c0


def jobs_for(source, per_kind, seed_start):
    if source == "inside":
        from bench_diagnosis import batch
        return [("inside", kind, cause, seed, ov) for kind, cause, seed, ov in
                batch(per_kind, seed_start) if kind != "wrong units"]
    from bench_diagnosis_outside import batch
    return [("outside", kind, kind, seed, noise) for kind, noise, seed in
            batch(per_kind, seed_start)]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--source", choices=("inside", "outside"), default="inside",
                    help="records of bench_diagnosis.py (inside) or "
                         "bench_diagnosis_outside.py (outside)")
    ap.add_argument("--per-kind", type=int, default=1)
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--seed-start", type=int, default=None,
                    help="default: that benchmark's own (1000 inside, 21000 outside)")
    ap.add_argument("--limit", type=int, default=None, help="only the first N records")
    a = ap.parse_args(argv)
    seed = a.seed_start if a.seed_start is not None else (1000 if a.source == "inside" else 21000)
    js = jobs_for(a.source, a.per_kind, seed)[:a.limit]
    t0 = time.perf_counter()
    res = []
    with tempfile.TemporaryDirectory() as tmp:
        js = [j + (tmp,) for j in js]
        if a.jobs > 1:
            from concurrent.futures import ProcessPoolExecutor
            with ProcessPoolExecutor(a.jobs) as ex:
                res = list(ex.map(_one, js))
        else:
            res = [_one(j) for j in js]
    by = collections.defaultdict(list)
    for kind, seed, sc, named, why, cpu in res:
        by[kind].append((seed, sc, named, why))
        line = " ".join(f"{k} {sc[k]:.2f}" for k in MODELS if k in sc)
        print(f"{kind:28s} seed {seed}: named {named}; RMS [µm] {line}"
              + (f"; not exported: {why}" if why else "") + f" ({cpu:.0f} s CPU)")
    print()
    print("| records | n | " + " | ".join(MODELS) + " | best: " + "/".join(MODELS) + " |")
    print("|---|---|" + "---|" * len(MODELS) + "---|")
    total_best = collections.Counter()
    ext_vs_peer = []
    for kind, rs in list(by.items()) + [("all", [r for v in by.values() for r in v])]:
        rs = [r for r in rs if r[1]]
        med = [np.median([r[1][k] for r in rs if k in r[1]]) if any(k in r[1] for r in rs)
               else np.nan for k in MODELS]
        best = collections.Counter(min(r[1], key=r[1].get) for r in rs)
        if kind == "all":
            total_best = best
            ext_vs_peer = [r[1]["extended"] - min(r[1][k] for k in ("tf", "arx") if k in r[1])
                           for r in rs if "extended" in r[1]
                           and any(k in r[1] for k in ("tf", "arx"))]
        print(f"| {kind} | {len(rs)} | " + " | ".join(f"{v:.2f}" for v in med) + " | "
              + "/".join(str(best.get(k, 0)) for k in MODELS) + " |")
    print()
    n_all = sum(total_best.values())
    print(f"Best model over {n_all} records: " + ", ".join(f"{k} {total_best.get(k, 0)}"
                                                         for k in MODELS))
    if ext_vs_peer:
        v = np.array(ext_vs_peer)
        print(f"Extended minus the better peer, on the {v.size} records with an extended "
              f"model: median {np.median(v):+.2f} µm, extended lower on {(v < 0).sum()}")
    print(f"wall {time.perf_counter() - t0:.0f} s, CPU {sum(r[5] for r in res):.0f} s in "
          f"the workers; load {os.getloadavg()}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
