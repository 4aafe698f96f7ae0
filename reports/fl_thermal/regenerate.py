"""Regenerate reports/fl_thermal/ from the real recording in ../shared/data/fl_thermal/.

    cd <repo> && python reports/fl_thermal/regenerate.py [--data DIR]

Hold-out: from t = 72 000 s (20 h) on -- the cooling after the 3750 rpm block and the
whole 5000 rpm block, a speed the calibration never saw (its C2 comes from the
early-rise mapping, paper eqs. 20-21). Everything is fitted on the first 20 h only.
The published table uses the default structure search (``narrow``); the experiments
table adds the ``wide`` search and a second hold-out (t >= 16.13 h), whose outputs are
not kept (numbers in experiments.json). About 10 min on 2 cores (``--jobs``).
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]
sys.path.insert(0, str(REPO))

from models.diagnosis.engine import diagnose_file  # noqa: E402
from scenarios.diagnose import run_diagnosis  # noqa: E402
from scenarios.io import atomic_write_text  # noqa: E402

HOLDOUT_S = 72000.0
#: second hold-out, added afterwards: from the 3750 rpm run-up on (16.13 h), fitted on
#: t < 16.13 h -- also opening with a speed the fit never saw (README, "Experiments")
HOLDOUT2_S = 58065.0


def _one(job):
    data, ch, hs, search, out = job
    toml = Path(data) / f"fl_thermal_ch{ch}.toml"
    if out is None:                       # experiments: numbers only, nothing written
        return job[1:4], diagnose_file(toml, hs, search).summary
    return job[1:4], run_diagnosis(toml, out, hs, True, search)


def _scores(s):
    h = s["holdout"]
    return h["baseline_rmse_um"], s["mlr"]["holdout_rmse_um"], h["extended_rmse_um"]


def _verdict(wins):
    return (f"**The extended model beats both the paper AR(1) and the MLR on {wins} of 5 "
            f"channels**" + (" — the requirement \"beat both on every channel\" is NOT met."
                             if wins < 5 else "."))


def main(argv=None) -> int:
    from concurrent.futures import ProcessPoolExecutor

    ap = argparse.ArgumentParser()
    ap.add_argument("--data", default=str(REPO.parent / "shared" / "data" / "fl_thermal"))
    ap.add_argument("--jobs", type=int, default=2)
    a = ap.parse_args(argv)
    chans = range(1, 6)
    jobs = [(a.data, ch, HOLDOUT_S, "narrow", HERE / f"ch{ch}") for ch in chans]
    jobs += [(a.data, ch, hs, se, None) for se, hs in (("wide", HOLDOUT_S),
                                                        ("narrow", HOLDOUT2_S),
                                                        ("wide", HOLDOUT2_S)) for ch in chans]
    with ProcessPoolExecutor(a.jobs) as ex:
        res = dict(ex.map(_one, jobs))

    rows, wins = [], 0
    for ch in chans:
        s = res[(ch, HOLDOUT_S, "narrow")]
        ar, ml, ext = _scores(s)
        beats = ext < ar and ext < ml
        wins += beats
        fs = s["selection"].get("frame_structure")
        rows.append(f"| ch{ch} | {s['cause']} | {ar:.2f} | {ml:.2f} | "
                    f"{s['ar_form']['ar_output_error']['baseline_holdout_rmse_um']:.2f} | "
                    f"{ext:.2f} | {fs['label'].replace(',', ', ') if fs else '–'} | "
                    f"{'yes' if beats else '**no**'} |")
    text = (HERE / "README.head.md").read_text()
    text += ("\n| channel | cause | paper AR(1) | MLR (eq. 18) | AR(1) output-error | extended | "
             "frame structure | extended beats AR and MLR |\n|---|---|---|---|---|---|---|---|\n"
             + "\n".join(rows) + "\n\n" + _verdict(wins) + "\n")

    exp = {}
    text += ("\n## Experiments after the first result (not the published procedure)\n\n"
             "Hold-out RMSE [µm]; *narrow* is the published procedure, *wide* the wider "
             "structure search (`--frame-search wide`); the selected wide structure in "
             "brackets. Regenerated with the rest by `regenerate.py`.\n\n"
             "| channel | hold-out | paper AR(1) | MLR | extended, narrow | extended, wide "
             "(structure) |\n|---|---|---|---|---|---|\n")
    tallies = {}
    for hs, name in ((HOLDOUT_S, "t ≥ 20 h"), (HOLDOUT2_S, "t ≥ 16.13 h")):
        for ch in chans:
            n, w = res[(ch, hs, "narrow")], res[(ch, hs, "wide")]
            ar, ml, en = _scores(n)
            ew = w["holdout"]["extended_rmse_um"]
            for se, e in (("narrow", en), ("wide", ew)):
                tallies[(name, se)] = tallies.get((name, se), 0) + (e < ar and e < ml)
            lab = w["selection"]["frame_structure"]["label"].replace(",", ", ")
            text += f"| ch{ch} | {name} | {ar:.2f} | {ml:.2f} | {en:.2f} | {ew:.2f} ({lab}) |\n"
            exp[f"ch{ch}@{hs:g}s"] = {"paper_ar_rmse_um": ar, "mlr_rmse_um": ml,
                                      "extended_narrow_rmse_um": en,
                                      "extended_wide_rmse_um": ew, "wide_structure": lab,
                                      "narrow_structure": n["selection"]["frame_structure"]["label"],
                                      "cause_narrow": n["cause"], "cause_wide": w["cause"]}
    text += "\nChannels where the extended model beats both: " + "; ".join(
        f"{name}, {se}: {k} of 5" for (name, se), k in tallies.items()) + ".\n"
    text += (HERE / "README.tail.md").read_text()
    atomic_write_text(HERE / "experiments.json", json.dumps(exp, indent=1) + "\n")
    atomic_write_text(HERE / "README.md", text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
