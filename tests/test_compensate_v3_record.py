"""``arfem compensate`` on a contract-v3 record (issue 33 item 4, issue 32 item 5): a
record naming its mesh scenario (``[model] scenario``) with one ``d_<sensor>_um`` column
per displacement channel and no ``growth_um``.

The box of tests/test_model_v2_export.py (three axes, two sources, the ambient
stepping) is run once; its record is rewritten as a v3 record (the ``[model]`` table,
``growth_um`` dropped) and replayed with the run's model.json (version 2).

What is verified and why:

* the replay gives one residual per axis (Y, Z, X, the model's order) below 1 % of the
  axis's RMS: the model is the run's own reduced solve, so only the CSV's 10 digits
  separate them (the same bound as the growth_um record's replay); a v3 record read
  with a wrong column, a lost input or rows shifted by one would miss it by far;
* the v3 record and the old-style record (``growth_um``, no ``[model]``) give the same
  figures to 1e-9: reading the v3 record changes nothing of the replay;
* bad input is one line, exit 2, ``--out`` not created: a model output without its
  ``d_`` column (the line names the column and what the record has), a version-1
  model on a v3 record (names the record's channels), a ``[model]`` scenario that is
  missing.
"""
from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

from test_model_v2_export import box_scenario


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    from arfem.scenarios.cli import main
    d = tmp_path_factory.mktemp("v3box")
    toml = box_scenario(d, 0.0)
    assert main(["run", str(toml), "--out", str(d / "run"), "--no-progress"]) == 0
    return d


def v3_record(d: Path, drop=("growth_um",), scenario: str = "../box.toml") -> Path:
    """The run's record as contract v3: ``[model] scenario``, without ``drop``."""
    with open(d / "run" / "record.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    keep = [k for k in rows[0] if k not in drop]
    out = d / "v3"
    out.mkdir(exist_ok=True)
    with open(out / "rec.csv", "w", newline="") as f:
        w = csv.DictWriter(f, keep, extrasaction="ignore")
        w.writeheader()
        w.writerows(rows)
    (out / "rec.toml").write_text(f'[dataset]\nname = "box-v3"\ncsv = "rec.csv"\n\n'
                                  f'[model]\nscenario = "{scenario}"\n')
    return out / "rec.toml"


def _one_line_refusal(capsys, argv, out: Path, words) -> None:
    from arfem.scenarios.cli import main
    capsys.readouterr()
    rc = main(argv)
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert rc == 2 and len(err) == 1, err
    for w in words:
        assert w in err[0], err
    assert not out.exists()


def test_v3_record_replays_per_axis_like_the_growth_record(run_dir, capsys):
    from arfem.scenarios.cli import main
    rec = v3_record(run_dir)
    assert "growth_um" not in (rec.parent / "rec.csv").read_text().splitlines()[0]
    model = run_dir / "run" / "model.json"
    assert main(["compensate", str(model), str(rec), "--out", str(run_dir / "o3")]) == 0
    s3 = json.loads((run_dir / "o3" / "summary.json").read_text("utf-8"))
    assert [a["axis"] for a in s3["axes"]] == ["Y", "Z", "X"] and s3["dataset"] == "box-v3"
    for a in s3["axes"]:
        assert a["rms_after_um"] < 0.01 * a["rms_before_um"], a
    assert main(["compensate", str(model), str(run_dir / "run" / "record.toml"), "--out",
                 str(run_dir / "o2")]) == 0
    s2 = json.loads((run_dir / "o2" / "summary.json").read_text("utf-8"))
    for a, b in zip(s3["axes"], s2["axes"]):
        assert a["rms_before_um"] == pytest.approx(b["rms_before_um"], rel=1e-9)
        assert a["rms_after_um"] == pytest.approx(b["rms_after_um"], rel=1e-9, abs=1e-12)
    with open(run_dir / "o3" / "compensated.csv", newline="") as f:
        head = next(csv.reader(f))
    assert {"residual_X_um", "residual_Y_um", "residual_Z_um"} <= set(head)


def test_v3_record_refusals_are_one_line(run_dir, capsys):
    model = run_dir / "run" / "model.json"
    out = run_dir / "refused"
    rec = v3_record(run_dir, drop=("growth_um", "d_tip_x_um"))
    _one_line_refusal(capsys, ["compensate", str(model), str(rec), "--out", str(out)], out,
                      ["d_tip_x_um", "it has", "d_tip_y_um"])
    rec = v3_record(run_dir)
    v1 = run_dir / "v1.json"
    from arfem.models.compensator import ar1_model
    from arfem.scenarios.compensation.model_file import write_model
    write_model(v1, ar1_model(0.99, 1e-4, dtau_s=60.0))
    _one_line_refusal(capsys, ["compensate", str(v1), str(rec), "--out", str(out)], out,
                      ["contract-v3", "d_tip_z_um", "version-2"])
    rec = v3_record(run_dir, scenario="nowhere.toml")
    _one_line_refusal(capsys, ["compensate", str(model), str(rec), "--out", str(out)], out,
                      ["model.scenario", "not found"])
