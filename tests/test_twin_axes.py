"""``arfem twin --scenario`` serves a ``[geometry]`` scenario with one offset node per axis,
and ``arfem compensate --live`` with the scenario's model.json (version 2) compensates
it over OPC UA (issue 32 item 5).

The scenario is the small box of tests/test_model_v2_export.py with speed-dependent
convection (h = 10 + 0.01 n): the model is speed-scheduled (model.json's
``speed_schedule``), so the live compensator reads ``speed_rpm`` from the twin's node
too, and the twin (the FEM, with noise) and the model differ only by the noise. Twin and compensator are separate
processes, the twin in lockstep (one interval per request that writes an offset), so
nothing depends on timing.

What is verified and why:

* the twin serves its run to the end (120 intervals of 60 s) and exits 0; every cycle
  was sent and none held;
* live equals replay per axis: the offsets the twin recorded on each axis are exactly
  (==) the compensator's log and those of ``arfem compensate``'s replay of the twin's
  record with the same per-axis limits; the twin's error per axis is its true
  displacement + that offset to 1e-12 µm (the same floats added);
* the per-axis limits hold on the wire (X: 15 µm, 0.3 µm/cycle; the others 50, 1), and
  the model reduces every axis's RMS error (the schedule is the reduced solve to
  round-off at the box's speeds: tests/test_model_speed_schedule.py).
"""
from __future__ import annotations

import csv
import json
import select
import subprocess
import sys

import numpy as np
import pytest

pytest.importorskip("asyncua")

from test_model_v2_export import box_scenario  # noqa: E402

ARFEM = [sys.executable, "-m", "arfem"]
NODE = "ns=2;s=Spindle.{}"
N = 120


def read_csv(path):
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    return {k: np.array([float(r[k]) if r[k] else np.nan for r in rows]) for k in rows[0]}


@pytest.mark.xdist_group("tcp_ports")   # takes a TCP port: see conftest.py
def test_twin_serves_a_geometry_scenario_per_axis(tmp_path):
    from arfem.scenarios.cli import main
    from arfem.scenarios.records.dataset import load_dataset
    from arfem.scenarios.compensation.model_file import read_model
    from arfem.scenarios.compensation.replay import replay
    toml = box_scenario(tmp_path, 0.01)
    assert main(["run", str(toml), "--out", str(tmp_path / "run")]) == 0
    model = read_model(tmp_path / "run" / "model.json")
    rec_dir = tmp_path / "rec"
    twin = subprocess.Popen(ARFEM + ["twin", "--scenario", str(toml), "--port", "0",
                                     "--lockstep", "--noise-um", "0.01", "--record",
                                     str(rec_dir)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        ready, _, _ = select.select([twin.stdout], [], [], 300)
        line = twin.stdout.readline() if ready else ""
        assert "listening on" in line, (line, twin.poll())
        url = line.split("listening on ")[1].strip()
        text = ('[live]\ntransport = "opcua"\nmax_offset_um = 50.0\nmax_step_um = 1.0\n'
                f'period_s = 0.01\ncycles = {N}\nstale_after_s = 600\nlog = "live.log"\n'
                '[live.axes.X]\nmax_offset_um = 15.0\nmax_step_um = 0.3\n'
                f'[opcua]\nendpoint = "{url}"\ntime_node = "{NODE.format("time_s")}"\n'
                'timeout_s = 2.0\nreconnect_initial_s = 0.1\nreconnect_max_s = 0.4\n'
                '[opcua.inputs]\n'
                + "".join(f'{i.name} = "{NODE.format(i.name)}"\n' for i in model.inputs)
                + "".join(f'[opcua.axes.{ax}]\noffset_node = "{NODE.format(f"offset_{ax}_um")}"\n'
                          f'alarm_node = "{NODE.format(f"alarm_{ax}")}"\n' for ax in model.axes))
        (tmp_path / "live.toml").write_text(text)
        r = subprocess.run(ARFEM + ["compensate", str(tmp_path / "run" / "model.json"),
                                    "--live", str(tmp_path / "live.toml")],
                           capture_output=True, text=True, timeout=600)
        assert r.returncode == 0, r.stderr
        assert twin.wait(timeout=120) == 0
    finally:
        if twin.poll() is None:
            twin.kill()
            twin.wait()
        twin.stdout.close()
        twin.stderr.close()
    log = [json.loads(x) for x in (tmp_path / "live.log").read_text().splitlines()]
    cyc = [c for c in log if "cycle" in c]
    assert len(cyc) == N and all(c["sent"] and not c["held"] for c in cyc)
    rec = read_csv(rec_dir / "twin.csv")
    assert rec["time_s"].size == N
    limits = {"X": (15.0, 0.3)}
    res = replay(model, load_dataset(rec_dir / "twin.toml"),
                      max_offset_um=tuple(limits.get(a, (50.0, 1.0))[0] for a in model.axes),
                      max_step_um=tuple(limits.get(a, (50.0, 1.0))[1] for a in model.axes),
                      use_observer=False)    # the live config has no thermometer node
    for j, ax in enumerate(model.axes):
        off = rec[f"offset_{ax}_um"]
        assert np.array_equal(off, [c["axes"][ax]["offset_um"] for c in cyc])
        assert np.array_equal(off, res.series.axes[j].offset_um)
        err = rec[f"true_{ax}_um"] + off
        assert np.max(np.abs(err - rec[f"error_{ax}_um"])) <= 1e-12
        clamp, step = limits.get(ax, (50.0, 1.0))
        assert np.max(np.abs(off)) <= clamp + 1e-12
        assert np.max(np.abs(np.diff(np.concatenate([[0.0], off])))) <= step + 1e-12
        rms = float(np.sqrt(np.mean(rec[f"true_{ax}_um"] ** 2)))
        assert float(np.sqrt(np.mean(err ** 2))) < rms, ax
    assert np.max(np.abs(rec["offset_X_um"])) == 15.0      # X's clamp binds


def test_twin_scenario_missing_or_rod_is_one_line(tmp_path, capsys):
    """A --scenario path that does not exist is named as not found (a typo), and a rod
    scenario as not a [geometry] one: one line each, exit 2, before any solve."""
    from arfem.scenarios.cli import main
    rod = tmp_path / "rod.toml"
    rod.write_text('[scenario]\nname = "r"\n')
    for path, says in ((tmp_path / "nosuch.toml", "file not found"),
                       (rod, "[geometry] table")):
        capsys.readouterr()
        rc = main(["twin", "--scenario", str(path), "--port", "0"])
        err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
        assert rc == 2 and len(err) == 1 and says in err[0], err
