"""Absurd sizes are refused up front, from an estimate of the work and memory, in one
line naming the key and --allow-large; malformed inputs that used to end in a traceback
are one line too. (Time and peak memory of each refusal: benchmarks/bench_limits.py.)
"""
from __future__ import annotations

import copy

import pytest

from arfem.io import read_toml
from arfem.params import InputError
from arfem.scenarios import config
from arfem.scenarios.cli import main
from arfem.scenarios.config import (builtin_scenario_path, estimate_cost, load_scenario,
                                    scenario_from_dict)

BASE = read_toml(builtin_scenario_path("paper_fig2"))


def _with(**tables) -> dict:
    d = copy.deepcopy(BASE)
    for table, kv in tables.items():
        node = d
        for part in table.split("."):
            node = node.setdefault(part, {})
        node.update(kv)
    return d


ABSURD = {   # the fuzzing pass's cases that ran for minutes (7.7 GB, 5.6 GB, 8.5 GB...)
    "dtau_1ms": (_with(ar={"dtau_s": 0.001}), "ar.dtau_s"),
    "backward_euler_1us": (_with(fem={"solver": "backward-euler", "dt_s": 1e-6}), "fem.dt_s"),
    "mesh_4096x4096": (_with(**{"fem.mesh": {"nr": 4096, "nz": 4096}}), "fem.mesh"),
    "mesh_3d_200_200_400": (_with(fem={"model": "3d"},
                                  **{"fem.mesh": {"n_core": 200, "n_ring": 200, "nz": 400}}),
                            "fem.mesh"),
    "snapshots_fields_off_elastic_on": (_with(outputs={"fields": False,
                                                       "field_interval_s": 0.5}),
                                        "outputs.field_interval_s"),
    "field_interval_1e-300": (_with(outputs={"field_interval_s": 1e-300}),
                              "outputs.field_interval_s"),
}


@pytest.mark.parametrize("case", sorted(ABSURD))
def test_absurd_scenarios_are_refused_by_the_loader(case):
    """Each is refused by scenario_from_dict (nothing built) naming its key; the size
    ones name --allow-large."""
    data, key = ABSURD[case]
    with pytest.raises(InputError) as ei:
        scenario_from_dict(data, "x.toml")
    msg = str(ei.value)
    assert "\n" not in msg and f"x.toml: {key}" in msg, msg
    if key != "outputs.field_interval_s":           # the snapshot bound is not lifted
        assert "--allow-large" in msg


def test_absurd_scenario_via_cli_is_one_line_and_out_untouched(tmp_path, capsys):
    """Through `arfem run`: exit 2, one line, --out not created."""
    p = tmp_path / "big.toml"
    p.write_text(builtin_scenario_path("paper_fig2").read_text()
                 + "\n[fem.mesh]\nnr = 4096\nnz = 4096\n")
    assert main(["run", str(p), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "fem.mesh" in err and "GiB" in err
    assert not (tmp_path / "o").exists()


def test_allow_large_lifts_the_size_limits(monkeypatch):
    """With --allow-large (ARFEM_ALLOW_LARGE=1, which the CLI flag sets) the same
    scenario loads; the snapshot bound and the per-direction bound stay."""
    monkeypatch.setenv("ARFEM_ALLOW_LARGE", "1")
    sc = scenario_from_dict(ABSURD["mesh_4096x4096"][0], "x.toml")
    assert sc.fem.mesh == {"nr": 4096, "nz": 4096}
    with pytest.raises(InputError, match="snapshots"):
        scenario_from_dict(ABSURD["field_interval_1e-300"][0], "x.toml")


def test_the_cli_flag_sets_allow_large(tmp_path, monkeypatch):
    """`--allow-large` is accepted by every subcommand and exported to the environment
    for the command's life (local worker processes inherit it), then restored."""
    import os

    import arfem.io
    monkeypatch.delenv("ARFEM_ALLOW_LARGE", raising=False)
    from arfem.scenarios.cli import build_parser
    p = build_parser()
    for argv in (["run", "x.toml", "--out", "o", "--allow-large"],
                 ["diagnose", "x.toml", "--out", "o", "--allow-large"],
                 ["allocate", "x.toml", "--out", "o", "--allow-large"],
                 ["sweep", "x.toml", "--out", "o", "--allow-large"]):
        assert p.parse_args(argv).allow_large
    seen = []
    monkeypatch.setattr(arfem.io, "read_text_utf8",
                        lambda *a, **k: seen.append(arfem.io.allow_large()) or "")
    main(["run", str(tmp_path / "x.toml"), "--out", str(tmp_path / "o"), "--allow-large"])
    assert seen == [True] and "ARFEM_ALLOW_LARGE" not in os.environ


def test_estimate_matches_the_built_models():
    """The unknown counts of the estimate are exact for the meshes arfem builds (the
    memory/work figures are built on them), checked against assembled models."""
    from arfem.scenarios.evaluation import build_model
    for tables in ({"fem.mesh": {"nr": 3, "nz": 10}},
                   {"fem": {"model": "3d", "order": 1},
                    "fem.mesh": {"n_core": 2, "n_ring": 1, "nz": 4}},
                   {"fem": {"model": "3d", "order": 2},
                    "fem.mesh": {"n_core": 3, "n_ring": 2, "nz": 4}}):
        sc = scenario_from_dict(_with(**tables), "x.toml")
        assert estimate_cost(sc)["ndofs"] == build_model(sc).ndofs


def test_shipped_scenarios_are_far_below_the_limits():
    """The paper's scenarios use under 5 % of each limit (the limits refuse typos, not
    studies)."""
    for name in ("paper_fig2", "paper_fig3"):
        c = estimate_cost(load_scenario(name))
        assert c["memory_bytes"] < 0.05 * config.MAX_MEMORY_BYTES
        assert c["work_flop"] < 0.05 * config.MAX_WORK_FLOP
        assert c["n_samples"] < 0.05 * config.MAX_TIME_STEPS


# -- tracebacks that are one line now ---------------------------------------------------

def test_toml_nested_600_deep_is_one_line(tmp_path, capsys):
    p = tmp_path / "deep.toml"
    p.write_text("x = " + "[" * 600 + "]" * 600 + "\n")
    assert main(["run", str(p), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "nested too deeply" in err


def test_toml_integer_over_4300_digits_is_one_line(tmp_path, capsys):
    p = tmp_path / "big.toml"
    p.write_text("[ar]\ndtau_s = " + "9" * 5000 + "\n")
    assert main(["run", str(p), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "malformed TOML" in err and "Traceback" not in err
