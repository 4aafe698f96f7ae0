"""``help(arfem)`` lists arfem's own modules, run from the checkout's root as the
README's Python example is: not the root's ``conftest`` nor a nested ``arfem``, while
``arfem.fem``, ``arfem.models`` and ``arfem.scenarios`` still import from the checkout.
"""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_help_lists_the_package_not_the_checkout_root():
    code = ("import pydoc, arfem, arfem.fem, arfem.models, arfem.scenarios.cli\n"
            "print(arfem.fem.__file__, arfem.models.__file__, arfem.scenarios.__file__)\n"
            "print(pydoc.render_doc(arfem, renderer=pydoc.plaintext))")
    r = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True,
                       text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    first, page = r.stdout.split("\n", 1)
    assert first.split() == [str(ROOT / d / "__init__.py") for d in ("fem", "models",
                                                                     "scenarios")]
    contents = page.split("PACKAGE CONTENTS", 1)[1].split("\n\n", 1)[0].split()
    assert "api" in contents and "conftest" not in contents and "arfem" not in contents
    assert "arfem.fem" in page.split("PACKAGE CONTENTS")[0]     # named in the docstring
