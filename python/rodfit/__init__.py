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
of :func:`experiment_text`'s rendering of it; errors found after reading (in a data file, a
case that does not solve) name the temporary copy of that text, ``experiment.yaml`` beside
the Tables' CSV files.
"""
from __future__ import annotations

import json
import os
import tempfile
import warnings
from typing import Any, Dict, Iterable, Mapping, Optional, Sequence, Union

import numpy as np

from . import _core
from ._core import Experiment, InputError, Profile, ProfileError, __version__  # noqa: F401

__all__ = [
    "Experiment", "FitError", "FitWarning", "InputError", "Profile", "ProfileError", "Runtime",
    "SimulateResult", "SolveError", "Table", "experiment", "experiment_text", "fit", "profile",
    "rollout", "simulate", "synth", "__version__",
]


class FitError(RuntimeError):
    """A fit that failed (it did not converge, or could not run): no profile."""


class SolveError(RuntimeError):
    """A case that did not solve (simulate), or a rollout that failed."""


class FitWarning(UserWarning):
    """A run's warning: a parameter the data do not determine, residuals beyond the stated
    noise, a stretched span ... (what the CLI prints as 'warning:')."""

PathLike = Union[str, "os.PathLike[str]"]

# The name a dict experiment has in messages, in its base folder.
_DICT_NAME = "<dict>"


class Table:
    """A data file given as an array: ``Table(array, columns=["s", "x", "y", "z"])`` or
    ``Table(s=..., x=..., y=..., z=...)`` (equal-length 1-D arrays); ``name="rest.csv"`` names
    the file (the profile and the report label the observation by it; default ``table<k>.csv``).

    Wherever an experiment dict takes a CSV file (an observation's ``file``, a ``drive``, a
    ``start`` shape ...) a Table may stand instead, with the columns that file would have
    (docs/formats.md, "CSV files"); NaN marks a missing value where the file may have one.
    It is written, every number at full precision (repr, so each float64 reads back to the same
    bits), as a CSV file that the experiment then names: the one reader reads it, with the same
    checks and messages (naming the column and the row's line in that file).
    """

    def __init__(self, data: Any = None, columns: Optional[Sequence[str]] = None, *,
                 name: Optional[str] = None, **named_columns: Any) -> None:
        # The CSV file's name (what the profile's and the report's tables call the
        # observation); default table<k>.csv.
        if name is not None and (os.path.basename(name) != name or not name.endswith(".csv")):
            raise ValueError(f"Table: name must be a file name ending in .csv, got {name!r}")
        self.name = name
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
    names = [t.name or f"table{k}.csv" for k, t in enumerate(tables)]
    if len(set(names)) != len(names):
        raise ValueError("experiment: two Tables have the same name")
    for table, name in zip(tables, names):
        path = os.path.join(folder.name, name)
        with open(path, "w", encoding="utf-8") as f:
            f.write(table.to_csv())
        paths.append(path)
    text = json.dumps(_fill_tables(plain, paths), indent=1, allow_nan=True) + "\n"
    text_file = os.path.join(folder.name, "experiment.yaml")
    with open(text_file, "w", encoding="utf-8") as f:
        f.write(text)
    anchor = os.path.join(os.path.abspath(os.fspath(base_dir or os.getcwd())), _DICT_NAME)
    result = _core.parse_experiment(text, anchor, parameters_optional)
    result._use_text_file(text_file)  # messages after reading name this copy of the text
    result._rodfit_files = folder
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


_read_profile = profile  # for functions whose argument is named `profile`


class Runtime(_core.Runtime):
    """The fitted rod at haptic rate (rodfit/runtime/runtime.h; docs/python.md, "Runtime").

    ``Runtime(profile, mode="quasi_static"|"dynamic", tool_s=None, tool="grasp"|"poke", ...)``:
    ``profile`` a path, a profile dict or a Profile; ``tool_s`` [m] the tool's arc length
    (default the tip); the other keywords are RuntimeOptions' (time_step [s], time_budget [s],
    gradient_tolerance, max_iterations, max_tool_move, max_strain, hold_orientation, ...).
    ``step(tool_position)`` -> force on the tool [N]; ``tool_position()``, ``shape()``,
    ``mesh()``, ``status()``.
    """

    def __init__(self, profile: Union[PathLike, Mapping[str, Any], Profile],
                 mode: str = "quasi_static", *, overrides: Optional[Mapping[str, float]] = None,
                 **options: Any) -> None:
        super().__init__(_read_profile(profile, overrides=overrides), mode, **options)


def synth(source: Union[PathLike, Mapping[str, Any], Experiment], *, seed: int = 1,
          noise_free: bool = False, output: Optional[PathLike] = None,
          base_dir: Optional[PathLike] = None) -> Dict[str, Any]:
    """Every observation file of the experiment synthesized from its parameter values (the
    truth), as ``rodfit synth`` makes them: ``{"files": {name: bytes}, "truth": {case: (n+1, 3)
    array [m]}, "report": [lines]}``; written into the folder ``output`` too when given (with its
    experiment.yaml; nothing written on an error). The same seed gives the same bytes."""
    ex = experiment(source, base_dir=base_dir)
    return _core.synth(ex, seed, noise_free, os.fspath(output) if output else "")


def fit(source: Union[PathLike, Mapping[str, Any], Experiment], *, threads: int = 2,
        output: Optional[PathLike] = None, report: Optional[PathLike] = None,
        base_dir: Optional[PathLike] = None) -> Dict[str, Any]:
    """Fits the experiment's ``fit: true`` parameters to its observations (the static fit, or
    the motion fit of a moving experiment), as ``rodfit fit`` does; returns the profile as a
    dict with the profile JSON's structure (docs/formats.md, "Profile JSON"): ``parameters``
    {name: {value, std, unit, identifiable, reason, ...}} in SI units, ``correlation``, ``fit``
    (its summary) ... ``output``: also write the profile JSON there; ``report``: also the
    report's folder (with ``output``). ``threads``: cases evaluated in parallel.

    Raises InputError for bad input, FitError when the fit fails. Issues a FitWarning per
    warning of the run, among them a fitted parameter the data do not determine (its value is
    then None) and residuals far beyond the stated noise (the model does not explain the
    data: do not use the values as they stand).
    """
    ex = experiment(source, base_dir=base_dir)
    run = _core.fit(ex, threads, os.fspath(output) if output else "",
                    os.fspath(report) if report else "")
    if not run["ok"]:
        raise FitError(run["error"])
    for text in run["warnings"]:
        warnings.warn(text, FitWarning, stacklevel=2)
    if not run["all_determined"]:
        warnings.warn("some fitted parameter is not determined by the data (value None in the "
                      "profile; its 'reason' says why)", FitWarning, stacklevel=2)
    return run["profile"]


class SimulateResult(dict):
    """What :func:`simulate` returns: a dict. Static scenes: {case: (n+1, 3) centre-line [m]};
    moving scenes: {case: {"t": (T,) [s], "x": (T, n+1, 3) [m], "s": [m], "reactions":
    {point: {"s", "position", "force" [N], "moment" [N m]: (T, 3)}}}}. Attributes: ``forces``
    (static: per held point of every case, case, point, s, position, force [N], moment [N m]),
    ``summary`` (per case, how its solve or integration ended), ``warnings``, ``moving``."""

    forces: list
    summary: list
    warnings: list
    moving: bool


def simulate(source: Union[PathLike, Mapping[str, Any], Experiment],
             profile: Union[None, PathLike, Mapping[str, Any], Profile] = None, *,
             overrides: Optional[Mapping[str, float]] = None,
             output: Optional[PathLike] = None, keep_going: bool = False,
             base_dir: Optional[PathLike] = None) -> SimulateResult:
    """Solves every case of a scene to static equilibrium, or integrates a moving scene (a
    ``dynamics:`` block) in time, as ``rodfit simulate`` does; with ``profile`` (a path, a dict
    as :func:`fit` returns, or a Profile) its fitted material replaces the scene's
    ``parameters:`` (which may then be left out; ``overrides`` {name: value} as for
    :func:`profile`). ``output``: also write the CLI's files there (shapes.csv ...).

    Returns a :class:`SimulateResult`. Raises InputError for bad input, SolveError when a case
    does not solve (with ``keep_going``, the cases that did are returned and the failure is
    warned about)."""
    ex = experiment(source, base_dir=base_dir, parameters_optional=profile is not None)
    prof = None if profile is None else _read_profile(profile, overrides=overrides)
    run = _core.simulate(ex, prof, os.fspath(output) if output else "", keep_going)
    if run["first_failure"]:
        if not keep_going:
            raise SolveError(run["first_failure"])
        warnings.warn(run["first_failure"], FitWarning, stacklevel=2)
    for text in run["warnings"]:
        warnings.warn(text, FitWarning, stacklevel=2)
    result = SimulateResult(run["motions"] if run["moving"] else run["shapes"])
    result.forces, result.summary = run["forces"], run["summary"]
    result.warnings, result.moving = run["warnings"], run["moving"]
    return result


def _recording_path(recording: Any, index: int, folder: str) -> str:
    """A recording as a file ReadRecordings reads: a path as is; an array (frames, markers, 3)
    [m], NaN where a marker was not seen, as a wide CSV (frame,x0,y0,z0,x1,...)."""
    if isinstance(recording, (str, os.PathLike)):
        return os.fspath(recording)
    frames = np.asarray(recording, dtype=np.float64)
    if frames.ndim != 3 or frames.shape[2] != 3:
        raise ValueError(f"recordings[{index}]: an array must have shape (frames, markers, 3), "
                         f"got {frames.shape}")
    columns = ["frame"] + [f"{c}{k}" for k in range(frames.shape[1]) for c in "xyz"]
    data = np.column_stack([np.arange(frames.shape[0], dtype=np.float64),
                            frames.reshape(frames.shape[0], -1)])
    path = os.path.join(folder, f"recording{index}.csv")
    with open(path, "w", encoding="utf-8") as f:
        f.write(Table(data, columns=columns).to_csv())
    return path


def rollout(source: Union[PathLike, Mapping[str, Any], Experiment],
            recordings: Iterable[Any], fit: Sequence[str] = (), *,
            frame_rate: Optional[float] = None, unit: str = "m",
            held_markers: Optional[Sequence[int]] = None, initial: Optional[str] = None,
            smooth_frames: Optional[int] = None, held_ends: Optional[str] = None,
            method: Optional[str] = None, max_evaluations: Optional[int] = None,
            marker_sigma: Optional[float] = None,
            output: Optional[PathLike] = None, report: Optional[PathLike] = None,
            base_dir: Optional[PathLike] = None) -> Dict[str, Any]:
    """Predicts recorded marker motions open-loop with the scene's rod (it needs a
    ``dynamics:`` block), as ``rodfit rollout`` does; with ``fit`` (parameter names, e.g.
    ["bend_stiffness", "bend_damping"]) first fits them to the recordings.

    ``recordings``: marker CSV paths (docs/formats.md, "marker recording") or arrays of shape
    (frames, markers, 3) [m, or mm with unit="mm"], NaN where not seen, which need
    ``frame_rate`` [Hz]. The settings (held_markers, initial, smooth_frames, held_ends, method,
    max_evaluations, marker_sigma) are ``rodfit rollout``'s options (docs/cli.md): one left out
    (None) keeps the library's default, the one the command line has. Returns {"recordings": [{"predicted": (frames, markers, 3) [m],
    "marker_s" [m], "held", "mae_all" [m], "mae_predicted" [m], ...}], "fit": motion_fit.json
    as Python data or None, "profile": the fit's profile.json as Python data (the rod as
    fitted, its rest shape in rod.rest_shape; a path for ``simulate(profile=...)`` and
    ``Runtime``) or None, "error_all" [m], "error_predicted" [m], "warnings", "misfit",
    "failures" (per recording whose rollout failed: "FILE: reason"; the others ran),
    "fit_not_converged", "fit_undetermined"} -- what ``rodfit rollout`` exits 5, 3 and 4 for,
    each also issued as a FitWarning (a fit that did not converge returns its best point).
    Raises InputError for bad input, SolveError when every rollout fails or the fit cannot run."""
    ex = experiment(source, base_dir=base_dir)
    if unit not in ("m", "mm"):
        raise ValueError(f"unit: must be 'm' or 'mm', got {unit!r}")
    # Only the settings given: the native side reads them through the options' declarations
    # (their ranges and words) and keeps its defaults for the rest.
    given = {"held_markers": held_markers, "initial": initial, "smooth_frames": smooth_frames,
             "held_ends": held_ends, "method": method, "max_evaluations": max_evaluations,
             "marker_sigma": marker_sigma}
    settings = {key: value for key, value in given.items() if value is not None}
    with tempfile.TemporaryDirectory(prefix="rodfit-") as folder:
        paths = [_recording_path(r, k, folder) for k, r in enumerate(recordings)]
        run = _core.rollout(ex, paths, float(frame_rate or 0.0), unit == "mm", list(fit),
                            settings, os.fspath(output) if output else "",
                            os.fspath(report) if report else "")
    if not run["ok"]:
        raise SolveError(run["error"])
    for text in run["warnings"]:
        warnings.warn(text, FitWarning, stacklevel=2)
    for text in run["failures"]:
        warnings.warn("rollout failed: " + text, FitWarning, stacklevel=2)
    if run["fit_not_converged"] and run["fit"] is not None:
        warnings.warn("the fit did not converge: " + str(run["fit"].get("message", "")) +
                      " (its best point returned)", FitWarning, stacklevel=2)
    return run
