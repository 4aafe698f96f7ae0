"""``model.json``: the state-space model a compensator runs (``docs/model-json.md``).

Reading refuses, in one line naming the file and the key, a file that is not JSON
(the non-standard tokens ``NaN`` and ``Infinity`` included), of another ``model_version``,
with a key of the wrong type, matrices of the wrong shape or not finite, a negative
variance, or a model that would not settle (one strict reading,
:meth:`arfem.models.compensator.StateSpaceModel.from_dict`, which
``docs/model.schema.json`` states as a JSON Schema); :func:`check_inputs` refuses a model whose inputs the record or
stream lacks, before any offset is computed.
"""
from __future__ import annotations

import json
from pathlib import Path

from arfem.io import read_text_utf8, write_json
from arfem.models.compensator import StateSpaceModel
from arfem.params import InputError

__all__ = ["read_model", "write_model", "check_inputs"]


def read_model(path, limits=None) -> StateSpaceModel:
    """Read and validate ``model.json``.

    Raises
    ------
    InputError
        ``<file>: <key>: <what is wrong>``.
    """
    text = read_text_utf8(path, limits=limits)

    def constant(token):
        raise InputError(f"holds {token}, which is not a JSON number (every number of a "
                         "model must be finite)", str(path))
    try:
        doc = json.loads(text, parse_constant=constant)
    except InputError:
        raise
    except json.JSONDecodeError as exc:
        raise InputError(f"is not JSON ({exc.msg} at line {exc.lineno})", str(path)) from None
    except (ValueError, RecursionError) as exc:     # an integer of > 4300 digits, nesting
        raise InputError(f"is not JSON arfem can read ({' '.join(str(exc).split())[:80]})",
                         str(path)) from None
    return StateSpaceModel.from_dict(doc, str(path))


def write_model(path, model: StateSpaceModel) -> None:
    """Write ``model.json`` atomically."""
    write_json(Path(path), model.to_dict())


def check_inputs(model: StateSpaceModel, available, where: str) -> None:
    """Refuse a model that reads an input ``available`` lacks (one line naming them)."""
    missing = [i.name for i in model.inputs if i.name not in set(available)]
    if missing:
        raise InputError(f"the model reads {', '.join(missing)}, which this record does not "
                         f"have (it has {', '.join(sorted(available)) or 'no input'})", where)
