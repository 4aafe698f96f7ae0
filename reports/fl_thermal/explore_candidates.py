"""The exploratory run of README.posthoc.md 1.3.1 (development origins only).

    cd <repo> && python reports/fl_thermal/explore_candidates.py OUT.json [--jobs 2]

For every channel at the development origins (the odd ones: 16.13, 24.13, 32.13, 40.13,
44.13 h) it runs the post hoc ``--frame-search average`` procedure exactly as the
rolling evaluation does (``regenerate._roll_fit``: fitted on the growth before the
origin) and records, besides the three models' block RMSEs [µm], the block RMSE of
*every* candidate cause's fit and each candidate's naming test -- which the diagnosis
itself does not keep. The candidates are caught through the engine's ``on_fit`` hook
(the fit on the most rows is the one on the whole fit window). This is what
the drift-last variant was chosen from; it was run once, before the confirmation
origins were scored. ~18 min on 2 processes of the loaded shared machine.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

# regenerate.py beside this file: Python puts the running script's folder first on the
# module search path, so it imports as a plain module (loading it also sets one BLAS thread
# per process)
import regenerate as R

from arfem.models.diagnosis import engine as E
from arfem.models.diagnosis.rolling import blocks, speed_step_origins

_CAUGHT: dict = {}


def _keep(cause, rows, f):
    """The engine's on_fit hook: keep each cause's fit on the most rows."""
    n = int(rows.sum())
    if f is not None and n >= _CAUGHT.get((cause, "n"), 0):
        _CAUGHT[(cause, "n")] = n
        _CAUGHT[cause] = f


def one(ch, o_idx, search="average"):
    """Channel ``ch`` at origin number ``o_idx`` (from 0): models', candidates' block
    RMSEs [µm] and the naming tests."""
    toml = str(R.DATA / f"fl_thermal_ch{ch}.toml")
    ds = R._dataset(toml)
    t, y = np.asarray(ds.time_s), np.asarray(ds.growth_um)
    org = speed_step_origins(t, ds.speed_rpm, R.ROLL_START_S, R.ROLL_MIN_BLOCK_S)
    m = blocks(t, org)[o_idx] & ~ds.outliers
    n = int(np.searchsorted(t, org[o_idx]))
    _CAUGHT.clear()
    d = E.diagnose(R.origin_dataset(ds, n, y[:n]), float(t[n]), search, on_fit=_keep,
                   speed_engine=R.SPEED_ENGINE)

    def rm(p):
        return float(np.sqrt(np.mean((y - p)[m] ** 2)))
    s = d.series
    return {"ch": ch, "origin_h": org[o_idx] / 3600, "cause": d.cause,
            "paper_ar": rm(s["baseline_um"]), "mlr": rm(s["mlr_um"]),
            "extended": rm(s["extended_um"]),
            "candidates_block_rmse_um": {c: rm(f.prediction) for c, f in _CAUGHT.items()
                                         if isinstance(c, str)},
            "tests": {c["cause"]: {k: c.get(k) for k in ("score", "cv_per_block_um",
                                                         "median_block_ratio", "significant")}
                      for c in d.evidence.document["candidates"]}}


def main(argv=None) -> int:
    from concurrent.futures import ProcessPoolExecutor
    ap = argparse.ArgumentParser()
    ap.add_argument("out", help="JSON file to write")
    ap.add_argument("--jobs", type=int, default=2)
    a = ap.parse_args(argv)
    jobs = [(ch, i) for i in R.DEV_ORIGINS for ch in range(1, 6)]
    with ProcessPoolExecutor(a.jobs) as ex:
        res = list(ex.map(one, *zip(*jobs)))
    Path(a.out).write_text(json.dumps(res, indent=1, default=float) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
