"""rodfit for Python: fit Cosserat-rod material parameters, simulate scenes, run the fitted rod.

The package is a thin layer over rodfit's C++ library (docs/python.md): every call below is one
of the library's entry points, the same code the ``rodfit`` command runs, with the GIL released
while it works. Units are SI throughout (m, N, s, Pa, N m^2 ...); arrays are float64 numpy
arrays, one row per point (x, y, z).

Experiments and scenes come in three forms, wherever a function takes one:

- a path to the YAML file (docs/formats.md);
- a dict with the YAML's structure (``{"rod": {...}, "parameters": {...}, "cases": [...]}``),
  whose data files may be given as :class:`Table` objects (numpy arrays with column names)
  instead of paths; relative paths in it are taken from ``base_dir`` (default: the current
  folder);
- an :class:`Experiment` made by :func:`experiment`.

Bad input raises :class:`InputError` (or :class:`ProfileError` for profiles), a ``ValueError``
whose ``str()`` is one line ``FILE:LINE: KEY: message`` and whose attributes ``file``, ``line``,
``key`` and ``message`` hold its parts. For a dict, FILE is ``BASE_DIR/<dict>`` and LINE the line
of :func:`experiment_text`'s rendering of it.
"""
from __future__ import annotations

import json
import os
import tempfile
from typing import Any, Dict, Iterable, Mapping, Optional, Sequence, Union

import numpy as np

from . import _core
from ._core import Experiment, InputError, Profile, ProfileError, __version__  # noqa: F401

__all__ = [
    "Experiment", "InputError", "Profile", "ProfileError", "Runtime", "Table", "experiment",
    "experiment_text", "fit", "profile", "rollout", "simulate", "synth", "__version__",
]

PathLike = Union[str, "os.PathLike[str]"]

# The name a dict experiment has in messages, in its base folder.
_DICT_NAME = "<dict>"


class Table:
    """A data file given as an array: ``Table(array, columns=["s", "x", "y", "z"])`` or
    ``Table(s=..., x=..., y=..., z=...)`` (equal-length 1-D arrays).

    Wherever an experiment dict takes a CSV file (an observation's ``file``, a ``drive``, a
    ``start`` shape ...) a Table may stand instead, with the columns that file would have
    (docs/formats.md, "CSV files"); NaN marks a missing value where the file may have one.
    It is written, every number at full precision (repr, so each float64 reads back to the same
    bits), as a CSV file that the experiment then names: the one reader reads it, with the same
    checks and messages (naming the column and the row's line in that file).
    """

    def __init__(self, data: Any = None, columns: Optional[Sequence[str]] = None,
                 **named_columns: Any) -> None:
        if data is not None and named_columns:
            raise TypeError("Table: give an array with columns=, or named columns, not both")
        if data is not None:
            array = np.asarray(data, dtype=np.float64)
            if array.ndim == 1:
                array = array[:, None]
            if array.ndim != 2:
                raise ValueError(f"Table: the array must be 2-D, got shape {array.shape}")
            if columns is None or len(columns) != array.shape[1]:
                raise ValueError(f"Table: columns= must name the array's {array.shape[1]} columns")
            self.columns = [str(c) for c in columns]
            self.data = array
        else:
            if not named_columns:
                raise ValueError("Table: no columns")
            arrays = [np.asarray(v, dtype=np.float64).ravel() for v in named_columns.values()]
            if len({len(a) for a in arrays}) != 1:
                raise ValueError("Table: the columns differ in length")
            self.columns = list(named_columns)
            self.data = np.column_stack(arrays)

    def to_csv(self) -> str:
        """The CSV text: a header row, then one row per array row (``nan`` for NaN)."""
        lines = [",".join(self.columns)]
        for row in self.data:
            lines.append(",".join("nan" if v != v else repr(float(v)) for v in row))
        return "\n".join(lines) + "\n"


def _plain(value: Any, tables: list) -> Any:
    """The dict's values as JSON can hold them: numpy arrays and scalars as lists and numbers,
    Tables as placeholders filled in by _write_tables."""
    if isinstance(value, Table):
        tables.append(value)
        return {"__rodfit_table__": len(tables) - 1}
    if isinstance(value, Mapping):
        return {str(k): _plain(v, tables) for k, v in value.items()}
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, (list, tuple)):
        return [_plain(v, tables) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    return value


def _fill_tables(value: Any, paths: Sequence[str]) -> Any:
    if isinstance(value, dict):
        if set(value) == {"__rodfit_table__"}:
            return paths[value["__rodfit_table__"]]
        return {k: _fill_tables(v, paths) for k, v in value.items()}
    if isinstance(value, list):
        return [_fill_tables(v, paths) for v in value]
    return value


def experiment_text(source: Mapping[str, Any], table_paths: Optional[Sequence[str]] = None) -> str:
    """The YAML text (JSON, a subset of YAML) a dict experiment is read as; the line numbers of
    an InputError about a dict are this text's. Tables appear as ``<table k>`` unless their
    file paths are given."""
    tables: list = []
    plain = _plain(source, tables)
    paths = table_paths if table_paths is not None else [f"<table {k}>" for k in range(len(tables))]
    return json.dumps(_fill_tables(plain, paths), indent=1, allow_nan=True) + "\n"


def experiment(source: Union[PathLike, Mapping[str, Any], Experiment], *,
               base_dir: Optional[PathLike] = None,
               parameters_optional: bool = False) -> Experiment:
    """An experiment or scene, read and validated: from a YAML path, a dict with the YAML's
    structure (Tables for data files; relative paths from ``base_dir``, default the current
    folder), or an Experiment (returned as is). ``parameters_optional``: a scene whose material
    a profile supplies may leave out ``parameters:``. Raises InputError (file:line:key)."""
    if isinstance(source, Experiment):
        return source
    if isinstance(source, (str, os.PathLike)):
        return _core.load_experiment(os.fspath(source), parameters_optional)
    if not isinstance(source, Mapping):
        raise TypeError("experiment: a path, a dict or an Experiment, got "
                        f"{type(source).__name__}")
    tables: list = []
    plain = _plain(source, tables)
    # The data files and the text, kept with the Experiment for as long as it lives: the fit
    # reads the files when it runs, synth reads the text again.
    folder = tempfile.TemporaryDirectory(prefix="rodfit-")
    paths = []
    for k, table in enumerate(tables):
        path = os.path.join(folder.name, f"table{k}.csv")
        with open(path, "w", encoding="utf-8") as f:
            f.write(table.to_csv())
        paths.append(path)
    text = json.dumps(_fill_tables(plain, paths), indent=1, allow_nan=True) + "\n"
    text_file = os.path.join(folder.name, "experiment.yaml")
    with open(text_file, "w", encoding="utf-8") as f:
        f.write(text)
    anchor = os.path.join(os.path.abspath(os.fspath(base_dir or os.getcwd())), _DICT_NAME)
    result = _core.parse_experiment(text, anchor, parameters_optional)
    result._rodfit_files = folder
    result._rodfit_text_file = text_file
    return result


def profile(source: Union[PathLike, Mapping[str, Any], Profile], *,
            overrides: Optional[Mapping[str, float]] = None) -> Profile:
    """A profile, read and validated: from a profile JSON path, a dict with its structure (what
    :func:`fit` returns) or a Profile. ``overrides`` {name: value [SI]} supply parameters the
    fit left undetermined (null) or replace others. Raises ProfileError (file: key: message)."""
    if isinstance(source, Profile):
        if overrides:
            raise ValueError("profile: overrides apply when a profile is read (path or dict)")
        return source
    values = {str(k): float(v) for k, v in (overrides or {}).items()}
    if isinstance(source, (str, os.PathLike)):
        return _core.load_profile(os.fspath(source), values)
    if isinstance(source, Mapping):
        return _core.parse_profile(json.dumps(_plain(source, [])), _DICT_NAME, values)
    raise TypeError(f"profile: a path, a dict or a Profile, got {type(source).__name__}")


class Runtime(_core.Runtime):
    """The fitted rod at haptic rate (rodfit/runtime/runtime.h; docs/python.md, "Runtime").

    ``Runtime(profile, mode="quasi_static"|"dynamic", tool_s=None, tool="grasp"|"poke", ...)``:
    ``profile`` a path, a profile dict or a Profile; ``tool_s`` [m] the tool's arc length
    (default the tip); the other keywords are RuntimeOptions' (time_step [s], time_budget [s],
    gradient_tolerance, max_iterations, max_tool_move, max_strain, hold_orientation, ...).
    ``step(tool_position)`` -> force on the tool [N]; ``tool_position()``, ``shape()``,
    ``mesh()``, ``status()``.
    """

    def __init__(self, profile_source: Union[PathLike, Mapping[str, Any], Profile],
                 mode: str = "quasi_static", *, overrides: Optional[Mapping[str, float]] = None,
                 **options: Any) -> None:
        super().__init__(profile(profile_source, overrides=overrides), mode, **options)


def synth(source: Union[PathLike, Mapping[str, Any], Experiment], *, seed: int = 1,
          noise_free: bool = False, output: Optional[PathLike] = None,
          base_dir: Optional[PathLike] = None) -> Dict[str, Any]:
    """Every observation file of the experiment synthesized from its parameter values (the
    truth), as ``rodfit synth`` makes them: ``{"files": {name: bytes}, "truth": {case: (n+1, 3)
    array [m]}, "report": [lines]}``; written into the folder ``output`` too when given (with its
    experiment.yaml; nothing written on an error). The same seed gives the same bytes."""
    ex = experiment(source, base_dir=base_dir)
    text_file = getattr(ex, "_rodfit_text_file", "")
    return _core.synth(ex, seed, noise_free, os.fspath(output) if output else "", text_file)
