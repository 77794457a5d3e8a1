# Type stubs of the rodfit package (docs/python.md). Units: SI (m, N, s, Pa, N m^2, N m).
import os
from typing import Any, Dict, Iterable, List, Mapping, Optional, Sequence, Union

import numpy as np
import numpy.typing as npt

__version__: str

PathLike = Union[str, os.PathLike[str]]
Vec3 = npt.NDArray[np.float64]          # shape (3,)
Points = npt.NDArray[np.float64]        # shape (n, 3)
ArrayLike3 = Union[npt.ArrayLike, Sequence[float]]

class InputError(ValueError):
    """'FILE:LINE: KEY: message'; line None when unknown."""
    file: str
    line: Optional[int]
    key: str
    message: str

class ProfileError(ValueError):
    """'FILE: KEY: message'."""
    file: str
    line: None
    key: str
    message: str

class FitError(RuntimeError): ...
class SolveError(RuntimeError): ...
class FitWarning(UserWarning): ...

class Experiment:
    @property
    def path(self) -> str: ...
    @property
    def case_names(self) -> List[str]: ...
    @property
    def moving(self) -> bool: ...
    @property
    def length(self) -> float: ...          # [m]
    @property
    def segments(self) -> int: ...

class Profile:
    @property
    def path(self) -> str: ...
    @property
    def version(self) -> int: ...
    @property
    def length(self) -> float: ...          # [m]
    @property
    def segments(self) -> int: ...
    @property
    def values(self) -> Dict[str, float]: ...  # [SI, each parameter's unit]

class Table:
    columns: List[str]
    data: npt.NDArray[np.float64]
    name: Optional[str]
    def __init__(self, data: Any = ..., columns: Optional[Sequence[str]] = ..., *,
                 name: Optional[str] = ..., **named_columns: npt.ArrayLike) -> None: ...
    def to_csv(self) -> str: ...

ExperimentSource = Union[PathLike, Mapping[str, Any], Experiment]
ProfileSource = Union[PathLike, Mapping[str, Any], Profile]

def experiment(source: ExperimentSource, *, base_dir: Optional[PathLike] = ...,
               parameters_optional: bool = ...) -> Experiment: ...
def experiment_text(source: Mapping[str, Any],
                    table_paths: Optional[Sequence[str]] = ...) -> str: ...
def profile(source: ProfileSource, *,
            overrides: Optional[Mapping[str, float]] = ...) -> Profile: ...

def fit(source: ExperimentSource, *, threads: int = ..., output: Optional[PathLike] = ...,
        report: Optional[PathLike] = ..., base_dir: Optional[PathLike] = ...) -> Dict[str, Any]:
    """The profile JSON as a dict (parameters, correlation, fit summary ...)."""

class SimulateResult(Dict[str, Any]):
    forces: List[Dict[str, Any]]
    summary: List[Dict[str, Any]]
    warnings: List[str]
    moving: bool

def simulate(source: ExperimentSource, profile: Optional[ProfileSource] = ..., *,
             overrides: Optional[Mapping[str, float]] = ..., output: Optional[PathLike] = ...,
             keep_going: bool = ..., base_dir: Optional[PathLike] = ...) -> SimulateResult: ...

def rollout(source: ExperimentSource, recordings: Iterable[Union[PathLike, npt.ArrayLike]],
            fit: Sequence[str] = ..., *, frame_rate: Optional[float] = ..., unit: str = ...,
            held_markers: Optional[Sequence[int]] = ..., initial: Optional[str] = ...,
            smooth_frames: Optional[int] = ..., held_ends: Optional[str] = ...,
            method: Optional[str] = ..., max_evaluations: Optional[int] = ...,
            marker_sigma: Optional[float] = ..., output: Optional[PathLike] = ...,
            report: Optional[PathLike] = ..., base_dir: Optional[PathLike] = ...) -> Dict[str, Any]: ...

def synth(source: ExperimentSource, *, seed: int = ..., noise_free: bool = ...,
          output: Optional[PathLike] = ..., base_dir: Optional[PathLike] = ...) -> Dict[str, Any]:
    """{'files': {name: bytes}, 'truth': {case: (n+1, 3) [m]}, 'report': [str]}"""

class Runtime:
    def __init__(self, profile: ProfileSource, mode: str = ..., *,
                 overrides: Optional[Mapping[str, float]] = ...,
                 tool_s: Optional[float] = ..., tool: str = ..., time_step: float = ...,
                 time_budget: float = ..., gradient_tolerance: float = ...,
                 step_tolerance: float = ..., max_iterations: int = ...,
                 dynamic_newton_iterations: int = ..., max_tool_move: float = ...,
                 max_strain: float = ..., mesh_ring_vertices: int = ...,
                 hold_orientation: bool = ...) -> None: ...
    def step(self, tool: Optional[ArrayLike3] = ...,
             tool_rotation: Optional[npt.ArrayLike] = ...) -> Vec3:
        """One tick; the force on the tool [N]."""
    def status(self) -> Dict[str, Any]: ...
    def tool_position(self) -> Vec3: ...      # [m]
    def tool_force(self) -> Vec3: ...         # [N]
    def tool_torque(self) -> Vec3: ...        # [N m]
    def tool_orientation(self) -> npt.NDArray[np.float64]: ...  # (3, 3)
    def shape(self) -> Points: ...            # (n+1, 3) [m]
    def mesh(self) -> Dict[str, Any]: ...     # vertices (V, 3) [m], triangles (T, 3)
    def energy(self) -> float: ...            # [J]
    def kinetic_energy(self) -> float: ...    # [J]
    @property
    def time(self) -> float: ...              # [s]
