"""The thermometers' observer in live operation over JSON lines (issue 43 item 1).

The box that ``arfem run`` writes (tests/test_model_v2_export.py's scenario: three axes,
one thermometer T_mid_C) streamed line by line.

What is verified and why:

* the loop reads the thermometer with the inputs and answers what the observer
  corrected (each disturbance's estimate with its unit W or K, the innovation), and the
  write-ahead log holds the same and the estimates in its state (the live equality with
  the replay, observer included, is tests/test_live_axes.py's first test);
* an absurd thermometer (500 °C, outside the plausible range of a ``_C`` reading) is
  held with ``out_of_range:T_mid_C``: the offsets are still written (not held), the
  innovation is None, and the config may narrow a thermometer's range in
  ``[live.ranges]`` like an input's;
* a warm start restores the disturbance estimates: a second process continuing the
  stream on the same log answers exactly what one process would have;
* ``--no-observer`` live answers what the model without its observer answers (==).
"""
from __future__ import annotations

import io
import json
from dataclasses import replace

from test_live_axes import CONFIG, box, lines_of, run  # noqa: F401  (box: a fixture)

from arfem.scenarios.live.jsonl import Status, load_config, run_jsonl


def test_live_reads_the_thermometer_and_answers_what_it_corrected(box, tmp_path):
    run_dir, model, ds, inputs = box
    assert "T_mid_C" in inputs and model.observer.thermometers == ("T_mid_C",)
    rc, ans = run(tmp_path, model, lines_of(ds, inputs, stop=30), "a.log")
    assert rc == 0 and len(ans) == 29
    last = ans[-1]["observer"]
    assert set(last["disturbances"]) == {"P_heater_W", "P_side_W", "ambient_C"}
    assert last["units"] == {"P_heater_W": "W", "P_side_W": "W", "ambient_C": "K"}
    assert isinstance(last["innovations_K"]["T_mid_C"], float) and last["held"] == []
    log = [json.loads(x) for x in (tmp_path / "a.log").read_text().splitlines()]
    cyc = [e for e in log if "state" in e]
    assert cyc[-1]["observer"] == last
    assert cyc[-1]["state"]["disturbances"] == [last["disturbances"][k] for k in
                                                ("P_heater_W", "P_side_W", "ambient_C")]
    assert cyc[-1]["inputs"]["T_mid_C"] == inputs["T_mid_C"][29]


def test_an_absurd_thermometer_is_held_not_the_offset(box, tmp_path):
    run_dir, model, ds, inputs = box

    def absurd(k, row):
        return {**row, "T_mid_C": 500.0} if k == 10 else row
    rc, ans = run(tmp_path, model, lines_of(ds, inputs, stop=15, edit=absurd), "b.log")
    a = ans[9]
    assert "out_of_range:T_mid_C" in a["alarms"] and not a["held"]
    assert a["observer"]["held"] == ["T_mid_C"] and a["observer"]["innovations_K"] == \
        {"T_mid_C": None}
    assert all(isinstance(v["offset_um"], float) for v in a["axes"].values())
    assert not ans[10]["alarms"] or "out_of_range:T_mid_C" not in ans[10]["alarms"]
    # [live.ranges] narrows a thermometer like an input
    (tmp_path / "r.toml").write_text(CONFIG.format(log="r.log")
                                     + "[live.ranges]\nT_mid_C = [0.0, 21.0]\n")
    cfg = load_config(tmp_path / "r.toml", model)
    assert dict((n, (lo, hi)) for n, lo, hi in cfg.ranges)["T_mid_C"] == (0.0, 21.0)


def test_a_warm_start_restores_the_estimates(box, tmp_path):
    run_dir, model, ds, inputs = box
    lines = lines_of(ds, inputs, stop=40)
    _, one = run(tmp_path, model, lines, "one.log")
    _, first = run(tmp_path, model, lines[:20], "two.log")
    _, second = run(tmp_path, model, lines[20:], "two.log")
    assert first + second == one


def test_no_observer_live_is_the_open_loop(box, tmp_path):
    from arfem.scenarios.cli import build_parser
    from arfem.scenarios.live.jsonl import run_live
    run_dir, model, ds, inputs = box
    (tmp_path / "c.toml").write_text(CONFIG.format(log="c.log"))
    lines = "".join(lines_of(ds, inputs, stop=20))
    args = build_parser().parse_args(["compensate", str(run_dir / "model.json"), "--live",
                                      str(tmp_path / "c.toml"), "--no-observer"])
    out = io.StringIO()
    assert run_live(args, io.StringIO(lines), out, Status(0, io.StringIO())) == 0
    answers = [json.loads(x) for x in out.getvalue().splitlines()]
    ref_model = replace(model, observer=None)
    (tmp_path / "d.toml").write_text(CONFIG.format(log="d.log"))
    ref = io.StringIO()
    run_jsonl(ref_model, load_config(tmp_path / "d.toml", ref_model), io.StringIO(lines),
              ref, Status(0, io.StringIO()))
    assert answers == [json.loads(x) for x in ref.getvalue().splitlines()]
    assert len(answers) == 19 and all("observer" not in a for a in answers)
    with_obs = io.StringIO()
    args.no_observer = False
    (tmp_path / "c.log").unlink()
    assert run_live(args, io.StringIO(lines), with_obs, Status(0, io.StringIO())) == 0
    assert all("observer" in json.loads(x) for x in with_obs.getvalue().splitlines())


def test_opcua_reads_thermometer_nodes_beside_the_inputs(box):
    """``[opcua.inputs]`` may name the observer's thermometers (then the loop reads
    them after the inputs); a name that is neither is refused in one line."""
    import pytest

    from arfem.params import InputError
    from arfem.scenarios.live.opcua import parse_config
    run_dir, model, ds, inputs = box
    nodes = {i.name: f"ns=2;s={i.name}" for i in model.inputs}
    table = {"endpoint": "opc.tcp://127.0.0.1:4840", "inputs": {**nodes,
             "T_mid_C": "ns=2;s=T_mid_C"}, "axes": {ax: {"offset_node": f"ns=2;s={ax}"}
                                                  for ax in model.axes}}
    cfg = parse_config(table, "live.toml", model)
    assert [nm for nm, _ in cfg.inputs] == [i.name for i in model.inputs] + ["T_mid_C"]
    plain = parse_config({**table, "inputs": nodes}, "live.toml", model)
    assert [nm for nm, _ in plain.inputs] == [i.name for i in model.inputs]
    with pytest.raises(InputError, match="inputs.T_other_C: the model does not read"):
        parse_config({**table, "inputs": {**nodes, "T_other_C": "ns=2;s=x"}}, "live.toml",
                     model)
