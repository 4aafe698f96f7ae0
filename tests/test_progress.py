"""Progress lines: shown for each slow step of `run` on a terminal, silent otherwise."""
from __future__ import annotations

import io

from arfem.scenarios.cli import main
from arfem.scenarios.progress import Progress
from arfem.scenarios.rod.outputs import run_scenario
from scenario_texts import small_scenario

SMALL = small_scenario(fields=True, picture=True, field_interval_s=1800.0)


def test_run_reports_every_slow_step_on_a_terminal(tmp_path):
    """With a terminal, the progress line names each slow step of `run` as it starts
    (FEM solve, field solve, XDMF, 3D picture, figure, report) and ends with 'done'."""
    case = tmp_path / "case.toml"
    case.write_text(SMALL, encoding="utf-8")
    buf = io.StringIO()
    with Progress(7, "arfem run", file=buf, tty=True) as progress:
        run_scenario(case, tmp_path / "out", progress=progress)
    text = buf.getvalue()
    for step in ("FEM solve", "AR(1)", "FEM fields", "fields.xdmf3", "3D picture", "figure",
                 "report.html", "done (7/7 steps done)"):
        assert step in text, step


def test_progress_is_silent_off_a_terminal_and_with_the_flag(tmp_path, capsys):
    """stderr that is not a terminal (pytest's capture, a log, CI) gets no progress line;
    --no-progress is accepted; stdout keeps the one summary line."""
    case = tmp_path / "case.toml"
    case.write_text(SMALL.replace("fields = true", "fields = false")
                    .replace("picture = true", "picture = false"), encoding="utf-8")
    assert main(["run", str(case), "--out", str(tmp_path / "a")]) == 0
    assert main(["run", str(case), "--out", str(tmp_path / "b"), "--no-progress"]) == 0
    out, err = capsys.readouterr()
    assert err == ""
    assert len(out.strip().splitlines()) == 2
    buf = io.StringIO()
    with Progress(2, "x", enabled=False, file=buf, tty=True) as p:
        p("step")
    assert buf.getvalue() == ""
