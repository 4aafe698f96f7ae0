"""The ``arfem`` command.

Subcommands (each lives in its own module and registers itself here):

    arfem run SCENARIO --out DIR [--force]     one scenario: FEM vs AR(1), all outputs
    arfem reproduce [--out DIR]                the paper's Fig. 2 and 3 into reports/paper/
    arfem sweep SWEEP.toml --out DIR           parameter sweep (local processes or Dask)
    arfem diagnose CASE.toml --out DIR         what a simulation gets wrong on measured data
    arfem allocate SCENARIO --out DIR          precision allocation over a motion chain
    arfem compensate MODEL RECORD --out DIR    replay a compensator on a measured record
    arfem compensate MODEL --live CONFIG       run it live (JSON lines or OPC UA)
    arfem twin [--port 0] [--lockstep]         a simulated spindle behind OPC UA

Bad input ends with one line ``arfem: error: <where>: <what>`` and exit status 2.
"""
from __future__ import annotations

import argparse
import importlib
import sys

from arfem import __version__
from arfem.limits import Limits
from arfem.params import InputError, one_line

#: subcommand -> module that defines ``add_parser(subparsers)`` and ``main(args)``
COMMANDS = {
    "run": "arfem.scenarios.commands.run",
    "reproduce": "arfem.scenarios.commands.run",
    "sweep": "arfem.scenarios.commands.sweep",
    "diagnose": "arfem.scenarios.commands.diagnose",
    "allocate": "arfem.scenarios.commands.allocate",
    "check": "arfem.scenarios.commands.check",
    "report": "arfem.scenarios.commands.report",
    "compensate": "arfem.scenarios.commands.compensate",
    "twin": "arfem.scenarios.commands.twin",
}


class ArfemParser(argparse.ArgumentParser):
    """argparse with the house error format: one line, status 2 (argparse's own is a
    usage block and then the error). The parser of ``arfem`` and of every standalone
    ``python -m arfem...`` command, so that all refuse bad options alike."""

    def error(self, message):
        self.exit(2, f"arfem: error: {one_line(message)} (see '{self.prog} --help')\n")


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
    p = ArfemParser(
        prog="arfem",
        description="FEM thermo-elastic simulation of a spindle (the paper's rod, or your "
                    "own unit from a Gmsh mesh) against the AR(1) thermal-growth model (Du "
                    "et al. 2021), with sweeps, diagnosis of measured data and "
                    "compensation.")
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
    for sp in sub.choices.values():            # one flag, the same on every subcommand
        if not any("--allow-large" in a.option_strings for a in sp._actions):
            sp.add_argument("--allow-large", action="store_true",
                            help="lift arfem's size limits (mesh, time steps, samples, "
                                 "memory estimate, CSV size and rows); see README, "
                                 "'Safety of your files and limits'")
    if "diagnose" in sub.choices:
        sub.choices["diagnose"].add_argument(
            "--allow-csv-outside", action="store_true",
            help="read a dataset CSV outside the TOML's folder (its cells are then never "
                 "shown in error messages)")
    return p


def _error(message: str) -> int:
    print(f"arfem: error: {one_line(message)}", file=sys.stderr)
    return 2


def main(argv=None) -> int:
    parser = build_parser(command_in(sys.argv[1:] if argv is None else argv))
    args = parser.parse_args(argv)
    # the permissions, passed by the commands to their readers and workers as a value
    args.limits = limits_of(args)
    return _run(args)


def limits_of(args) -> Limits:
    """The :class:`arfem.limits.Limits` of a command's flags (``--allow-large``,
    ``--allow-csv-outside``), joined with those the user set in the environment."""
    return Limits(large=getattr(args, "allow_large", False),
                  csv_outside=getattr(args, "allow_csv_outside", False)) \
        | Limits.from_environment()


def _run(args) -> int:
    try:
        rc = args.func(args)
    except InputError as exc:
        return _error(str(exc))
    except OSError as exc:                     # disk full, permissions, name too long...
        what = exc.strerror or str(exc)
        return _error(f"{exc.filename}: {what}" if exc.filename else what)
    except (OverflowError, RecursionError) as exc:
        return _error(f"an input value is out of range ({exc})")
    except KeyboardInterrupt:
        print("arfem: interrupted", file=sys.stderr)
        return 130
    except MemoryError:
        return _error("out of memory; the input asks for more than this machine has "
                      "(a finer mesh, more field snapshots or a bigger grid than it can hold)")
    return int(rc or 0)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
