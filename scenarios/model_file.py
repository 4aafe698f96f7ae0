"""``model.json``: the state-space model a compensator runs (``docs/model-json.md``).

Reading refuses, in one line naming the file and the key, a file that is not JSON, of
another ``model_version``, with matrices of the wrong shape or not finite, or a model
that would not settle; :func:`check_inputs` refuses a model whose inputs the record or
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
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputError(f"is not JSON ({exc.msg} at line {exc.lineno})", str(path)) from None
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
