"""Type stubs of the native module (python/src/*.rs): the workspace's Rust
code behind the `softjoint` package."""
from os import PathLike
from typing import Callable, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np

TUNE_UNIT_CANDIDATES: int
RHEOLOGY_UNIT_CANDIDATES: int

class SoftjointError(Exception):
    """Any error of the package; its message is the Rust error's."""

class InputError(SoftjointError):
    """A scenario, plant file, measurement or argument was refused."""

class NonFiniteError(SoftjointError):
    """A result held a NaN or infinite number (the program's output checks)."""

class RunCutShortError(SoftjointError):
    """A closed-loop run ended before its end."""

class UnstableError(SoftjointError):
    """A simulation became unstable."""

class SweepError(SoftjointError):
    """A sweep's units do not add up, or its objective failed."""

class UnverifiedError(SoftjointError):
    """A result failed its own checks: a contour fit's frames (`.fit` holds
    the fit) or a dlo solve's shapes (`.solution` holds the solution)."""

class Scenario:
    @staticmethod
    def default() -> Scenario: ...
    @staticmethod
    def load(path: Union[str, PathLike[str]]) -> Scenario: ...
    @property
    def name(self) -> str: ...
    def to_toml(self) -> str: ...
    def columns(self) -> List[str]: ...

def simulate(scenario: Scenario) -> Tuple[Dict[str, np.ndarray], str]: ...

class PlantFile:
    @staticmethod
    def load(path: Union[str, PathLike[str]]) -> PlantFile: ...
    @staticmethod
    def from_text(text: str, name: str) -> PlantFile: ...
    @property
    def name(self) -> str: ...
    @property
    def text(self) -> str: ...
    def save(self, path: Union[str, PathLike[str]]) -> None: ...

def candidate_gains(
    plant: PlantFile, index: int, seed: int = 1, search_v_offset: bool = False
) -> Tuple[List[float], float, float, float]: ...
def tune_cost(
    plant: PlantFile,
    kp_v_per_deg: Sequence[float],
    ki_v_per_deg_s: float,
    integral_limit_v: float,
    v_offset_v: float,
    plant_index: int = 0,
    plants: int = 1,
    seed: int = 1,
) -> str: ...

class TuneSweep:
    def __init__(
        self,
        plant: PlantFile,
        candidates: int,
        plants: int,
        seed: int = 1,
        search_v_offset: bool = False,
    ) -> None: ...
    def request(self) -> Tuple[int, int, int, bool]: ...
    def units(self, size: int = ...) -> List[Tuple[int, int, int]]: ...
    def run_unit(self, index: int, start: int, end: int) -> str: ...
    def best_index(self, units: List[str]) -> int: ...
    def heldout_units(self) -> List[Tuple[int, int]]: ...
    def run_heldout_unit(self, best: int, manoeuvre: int, gains: int) -> str: ...
    def merge(self, units: List[str], heldout: List[str] = ...) -> str: ...
    def state(self, units: List[str]) -> str: ...
    def write_state(
        self, units: List[str], path: str
    ) -> Tuple[int, Optional[int], Optional[float]]: ...
    def reduce(self, units: List[str], heldout: Optional[List[str]] = None) -> str: ...

def rheology_units(n: int, size: int = ...) -> List[Tuple[int, int]]: ...

class RheologyProblem:
    def __init__(
        self,
        scenario_text: Optional[str] = None,
        measured: Optional[Tuple[str, str]] = None,
        params: int = 4,
        scenario_name: str = "scenario",
    ) -> None: ...
    def ranges(self) -> List[Tuple[str, float, float]]: ...
    def objective(self, genes: Sequence[float]) -> float: ...
    def scores(self, batch: List[List[float]]) -> List[float]: ...
    def calibrate(
        self,
        method: str = "ga",
        evaluations: int = 1000,
        seed: int = 1,
        evaluate_batch: Optional[Callable[[List[List[float]]], List[float]]] = None,
    ) -> str: ...

def contour_fit(
    text: str,
    name: str = "contour.csv",
    model: Optional[str] = None,
    knots: Optional[int] = None,
    time_knots: Optional[int] = None,
    lambda_: Optional[float] = None,
    solver: str = "reduced",
    samples: int = 200,
    signed_radii: bool = False,
) -> Tuple[
    str,
    List[Tuple[float, np.ndarray, np.ndarray, Optional[np.ndarray], Optional[np.ndarray]]],
]:
    """`softjoint contour fit` of a CSV's text: fit.json's fields as JSON
    text, and each fitted frame as (frame, x, y, angle_rad, radius)."""
    ...

def viscoelastic_simulate(
    text: str,
    k1_n_per_m: float,
    k2_n_per_m: float,
    b_n_s_per_m: float,
    name: str = "trial.csv",
) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """`softjoint viscoelastic simulate` of a CSV's text: (time_s,
    displacement_m, force_n)."""
    ...

def rope_simulate(
    text: Optional[str] = None, name: str = "built-in overhand scenario",
    check_step: bool = False,
) -> Tuple[str, np.ndarray, np.ndarray]:
    """`softjoint dlo rope` of a scenario's TOML text (None: the built-in
    overhand knot; check_step: `--check-step`): the summary as JSON text
    (status and self-checks included), the frames' times (s), and the
    node positions flat (frame, node, x/y/z; m)."""
    ...

def viscoelastic_fit(
    text: str, name: str = "trial.csv", uniform: bool = False
) -> Tuple[str, np.ndarray]:
    """`softjoint viscoelastic fit` of a trial CSV's text: the `--json`
    summary as JSON text and the fitted force at the samples (N)."""
    ...

def dlo_solve(
    text: str, name: str = "problem.toml"
) -> Tuple[str, Optional[str], List[Tuple[str, Optional[float], Dict[str, np.ndarray]]]]:
    """`softjoint dlo solve` of a problem's TOML text: the summary as JSON
    text (without `solve_s` and the file names), why it is unverified
    (None if verified), and each shape as (name, l_fraction, shape.csv's
    columns)."""
    ...

def contour_synth(
    case: str,
    n: int = 40,
    sigma: Optional[float] = None,
    every: int = 10,
    angles: int = 10,
    seed: int = 1,
) -> Tuple[str, Dict[str, np.ndarray], Dict[str, np.ndarray]]:
    """`softjoint contour synth --case CASE`: the summary's figures as JSON
    text, data.csv's columns and truth.csv's."""
    ...

class PushProblem:
    """A push prepared as `softjoint push simulate` prepares it."""
    def __init__(
        self,
        material: str = "sponge",
        site: str = "middle-long",
        video: Optional[Tuple[str, str]] = None,
        ref_element_px: float = 8.0,
        noise_seed: int = 1,
        integrator: str = "customised",
        mode: str = "both",
        nx: int = 20,
        ny: int = 10,
        cell_px: float = 1.0,
        repair: bool = True,
    ) -> None: ...
    def frames(self) -> int: ...
    def simulate(
        self,
        params: Optional[str] = None,
        params_name: str = "params",
        predicted_forces: bool = False,
    ) -> Tuple[str, List[str], Dict[str, np.ndarray]]:
        """`softjoint push simulate`: the `--json` summary as JSON text
        (without `out`), each frame's phase, frames.csv's numeric columns."""
        ...
    def objective(self, params: str, score: str = "f", params_name: str = "params") -> float:
        """The fitness `push calibrate --score SCORE` maximises (μ(F), or
        minus the contour distance in px) for parameters as JSON text."""
        ...
    def scores(self, genes: List[List[float]], score: str = "f") -> List[float]:
        """That fitness for each gene vector (the eight parameters in
        params.json's order), in order; NaN for a run that cannot be
        scored (the search ranks it last)."""
        ...

def identify_joint(
    log_text: str,
    log_name: str,
    prior_text: Optional[str] = None,
    prior_name: str = "prior",
    board_estimates: bool = False,
    fit_fraction: float = 0.75,
    max_iterations: int = 100,
    plant_file: Optional[str] = None,
    fits: Optional[Callable[[List[str]], List[str]]] = None,
) -> Tuple[str, str, bool]:
    """`softjoint identify joint --json`: the report's JSON text, the plant
    file's text, whether every plane was verified."""
    ...

def write_gains(path: str, gains: str) -> None: ...

class IdentifyProblem:
    """A joint's excitation log and the prior its identification starts
    from, read as `softjoint identify joint` reads them; runs the
    mechanics stage's start units that `identify joint --ray` sends."""
    def __init__(
        self,
        log_text: str,
        log_name: str,
        prior_text: Optional[str] = None,
        prior_name: str = "prior",
        board_estimates: bool = False,
    ) -> None: ...
    def fit(self, unit: str) -> str:
        """One start unit (JSON text) fitted: `{"fit": ...}` or
        `{"error": "..."}` as JSON text (every number as its bits)."""
        ...
    def cost(
        self, plane: int, values: Dict[str, float], fit_fraction: float = 0.75
    ) -> Tuple[float, int]:
        """The mechanics stage's cost (sum of squared scaled residuals) and
        the residuals' count, with `values` (by plant-file field) set in
        the prior."""
        ...
    @property
    def planes(self) -> int: ...

def viscoelastic_object(
    mesh: Optional[Tuple[str, str]] = None,
    script: Optional[Tuple[str, str]] = None,
    duration_s: float = 1.5,
    probe_every: int = 10,
    seed: int = 1,
    tensor: bool = False,
) -> Tuple[str, Dict[str, np.ndarray], Dict[str, np.ndarray], Dict[str, np.ndarray]]:
    """`softjoint viscoelastic object` on an OBJ's and a script's (text,
    name): the printed figures as JSON text, haptic.csv's columns,
    frames.csv's (`time_s` per frame; `displacement_m`, `force_n` flat),
    params.csv's (`fixed`, `damping_magnitude_n_s_per_m`)."""
    ...
