"""The README's Python example runs verbatim on the shipped data.

What is verified and why: issue 30 found the README's example did not fit the shipped
record (foreign column names, ``initial`` silently defaulted). Every ```python block of
README.md is executed, unchanged, in a fresh working directory that holds only the
shipped ``scenarios/data/fl_thermal`` folder (a symbolic link), as a user's clone would; an
exception fails the test. The example prints the record's ``initial``, which must be
the TOML's ``"unknown"``, and the columns, which must be the contract's names. It
diagnoses the whole shipped record once (about 12 s of CPU here), the price of running
the README's example as written.
"""
import contextlib
import io
import os
import re
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def _python_blocks(text: str) -> list[str]:
    return re.findall(r"^```python\n(.*?)^```", text, flags=re.S | re.M)


def test_readme_python_blocks_run_verbatim_on_the_shipped_record(tmp_path, monkeypatch):
    blocks = _python_blocks((REPO / "README.md").read_text(encoding="utf-8"))
    assert blocks, "README.md has no ```python block"
    (tmp_path / "scenarios" / "data").mkdir(parents=True)
    os.symlink(REPO / "scenarios" / "data" / "fl_thermal", tmp_path / "scenarios" / "data" / "fl_thermal")
    monkeypatch.chdir(tmp_path)
    out = io.StringIO()
    namespace: dict = {}
    with contextlib.redirect_stdout(out):
        for code in blocks:
            exec(compile(code, "README.md", "exec"), namespace)   # noqa: S102 - our README
    printed = out.getvalue()
    assert "unknown µm ['time_s', 'growth_um', 'speed_rpm']" in printed, printed
    rec = namespace["record"]
    assert rec.initial == "unknown" and rec.columns["growth_um"] == "ch2(um)"
    assert namespace["diagnosis"].summary["dataset"] == "fl_thermal_ch2"
