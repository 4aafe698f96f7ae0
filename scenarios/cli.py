"""The ``arfem`` command.

Subcommands (each lives in its own module and registers itself here):

    arfem run SCENARIO --out DIR [--force]     one scenario: FEM vs AR(1), all outputs
    arfem reproduce [--out DIR]                the paper's Fig. 2 and 3 into reports/paper/
    arfem sweep SWEEP.toml --out DIR           parameter sweep (local processes or Dask)
    arfem diagnose CASE.toml --out DIR         what a simulation gets wrong on measured data
    arfem allocate SCENARIO --out DIR          precision allocation over a motion chain

Bad input ends with one line ``arfem: error: <where>: <what>`` and exit status 2.
"""
from __future__ import annotations

import argparse
import importlib
import sys

from arfem import __version__
from arfem.params import InputError

#: subcommand -> module that defines ``add_parser(subparsers)`` and ``main(args)``
COMMANDS = {
    "run": "arfem.scenarios.run",
    "reproduce": "arfem.scenarios.run",
    "sweep": "arfem.scenarios.sweep",
    "diagnose": "arfem.scenarios.diagnose",
    "allocate": "arfem.scenarios.allocate",
    "check": "arfem.scenarios.check",
    "report": "arfem.scenarios.html_report",
}


class _Parser(argparse.ArgumentParser):
    """argparse with the house error format: one line, status 2 (argparse's own is a
    usage block and then the error)."""

    def error(self, message):
        self.exit(2, f"arfem: error: {message} (see '{self.prog} --help')\n")


def command_in(argv) -> str | None:
    """The subcommand ``argv`` names (its first non-option word), if it is one."""
    for a in argv:
        if not a.startswith("-"):
            return a if a in COMMANDS else None
    return None


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The ``arfem`` parser. With ``command``, only that subcommand's module is imported
    (start-up stays short: the diagnosis engine alone takes ~0.4 s to import); without,
    every subcommand is registered (``arfem --help``, an unknown command)."""
    p = _Parser(
        prog="arfem",
        description="FEM thermo-elastic simulation of a spindle rod against the AR(1) "
                    "thermal-growth model (Du et al. 2021), with sweeps and diagnosis of "
                    "measured data.")
    p.add_argument("--version", action="version", version=f"arfem {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND", required=True)
    seen = set()
    for name, modname in COMMANDS.items():
        if modname in seen or (command is not None and modname != COMMANDS[command]):
            continue
        seen.add(modname)
        try:
            mod = importlib.import_module(modname)
        except ModuleNotFoundError as exc:  # a subcommand not built yet
            if exc.name != modname:
                raise
            continue
        mod.add_parser(sub)
    return p


def main(argv=None) -> int:
    parser = build_parser(command_in(sys.argv[1:] if argv is None else argv))
    args = parser.parse_args(argv)
    try:
        rc = args.func(args)
    except InputError as exc:
        print(f"arfem: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("arfem: interrupted", file=sys.stderr)
        return 130
    except MemoryError:
        print("arfem: error: out of memory; the input asks for more than this machine has "
              "(a finer mesh, more field snapshots or a bigger grid than it can hold)",
              file=sys.stderr)
        return 2
    return int(rc or 0)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
