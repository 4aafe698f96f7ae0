"""``python -m arfem`` is the ``arfem`` command."""
import sys

from arfem.scenarios.cli import main

sys.exit(main())
