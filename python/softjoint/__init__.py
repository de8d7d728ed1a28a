"""softjoint from Python: the joint's closed loop, tuning costs, the
rheology objective, and sweeps as work units.

Every function hands its inputs to the Rust code the ``softjoint``
program runs (host-tools, plant-rheology) through the native module
``softjoint._native``; nothing is modelled again here. Results pass the
program's own output checks: a summary or objective holding a NaN or an
infinite number raises :class:`NonFiniteError` instead of being returned
(a trace row that would hold one cuts the run short there:
:class:`RunCutShortError`, as ``softjoint sim`` exits 1).
Errors are exceptions derived from :class:`SoftjointError` that carry the
Rust error's message (the file, field or argument it names).

The sweeps (``tune``, rheology calibration) are deterministic work units
and a reduction: :class:`TuneSweep` gives the units and reduces their
results; ``softjoint.ray_sweep`` runs the units as Ray tasks. Where the
units run does not change the result.

Contour fits (:func:`contour_fit`) are ``softjoint contour fit``'s, with
the fit's own checks: a fit with a frame that failed them raises
:class:`UnverifiedError` (the fit attached) unless asked to return it.

The 3-element viscoelastic model's trace (:func:`viscoelastic_simulate`)
is ``softjoint viscoelastic simulate``'s.

The 3-element model's fit (:func:`viscoelastic_fit`) is ``softjoint
viscoelastic fit``'s, and the measured-object pipeline
(:func:`viscoelastic_object`) ``softjoint viscoelastic object``'s.

The rope's run (:func:`rope_simulate`) is ``softjoint dlo rope``'s; the
static wire, belt or sequence (:func:`dlo_solve`) is ``softjoint dlo
solve``'s. Both come with their own checks: a run or answer that fails
them raises :class:`UnverifiedError` (the result attached) unless asked
to return it.

The contour test cases (:func:`contour_synth`) are ``softjoint contour
synth``'s.

The pushed block (:class:`PushProblem`, :func:`push_simulate`) is
``softjoint push simulate``'s, and :func:`push_objective` the fitness
``softjoint push calibrate`` maximises.

Left out so far: identification, push calibration and classification,
and writing plant or gains files from Python.
"""
from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Dict, List, Optional, Sequence, Union

import numpy as np

from . import _native
from ._native import (
    RHEOLOGY_UNIT_CANDIDATES,
    TUNE_UNIT_CANDIDATES,
    IdentifyProblem,
    InputError,
    NonFiniteError,
    PlantFile,
    PushProblem,
    RheologyProblem,
    RunCutShortError,
    Scenario,
    SoftjointError,
    SweepError,
    TuneSweep,
    UnstableError,
    UnverifiedError,
    rheology_units,
)

PathLike = Union[str, "os.PathLike[str]"]

__all__ = [
    "RHEOLOGY_UNIT_CANDIDATES",
    "TUNE_UNIT_CANDIDATES",
    "Gains",
    "Identification",
    "IdentifyProblem",
    "InputError",
    "NonFiniteError",
    "PlantFile",
    "RheologyProblem",
    "RunCutShortError",
    "Scenario",
    "SoftjointError",
    "SweepError",
    "Trace",
    "TuneSweep",
    "UnstableError",
    "UnverifiedError",
    "ContourFit",
    "ContourFrame",
    "contour_fit",
    "viscoelastic_simulate",
    "viscoelastic_fit",
    "ViscoelasticFit",
    "ViscoelasticObject",
    "viscoelastic_object",
    "RopeRun",
    "rope_simulate",
    "DloSolution",
    "dlo_solve",
    "ContourSynth",
    "contour_synth",
    "PushProblem",
    "PushRun",
    "push_problem",
    "push_simulate",
    "push_objective",
    "identify_joint",
    "load_plant",
    "load_scenario",
    "rheology_problem",
    "rheology_units",
    "simulate",
    "tune",
    "tune_cost",
    "write_gains",
]


def load_scenario(path: Optional[PathLike] = None) -> Scenario:
    """The joint scenario in ``path`` (TOML, as ``softjoint sim`` reads
    it), or the built-in default without one."""
    return Scenario.default() if path is None else Scenario.load(os.fspath(path))


@dataclass(frozen=True)
class Trace:
    """A closed-loop run: ``columns`` holds one NumPy array per column of
    ``softjoint sim --csv`` (``t_s``, ``<angle>_true_deg``,
    ``<angle>_estimate_deg`` — NaN where the CSV has an empty field, the
    controller having no estimate yet — ``<angle>_desired_deg``,
    ``v1_V``…, ``faults``), ``summary`` the ``--json`` summary."""

    columns: Dict[str, np.ndarray]
    summary: dict = field(repr=False)

    def __getitem__(self, name: str) -> np.ndarray:
        return self.columns[name]

    def __len__(self) -> int:
        return len(self.columns["t_s"])


def simulate(scenario: Union[Scenario, PathLike, None] = None) -> Trace:
    """Runs the joint's scenario (a :class:`Scenario`, a path, or the
    built-in default) under the firmware core, as ``softjoint sim`` does.

    Raises :class:`RunCutShortError` if the run ends early (the plant
    went unstable, or a trace row failed its finite check; the message
    names the step and the cause), :class:`NonFiniteError` for a
    non-finite summary, :class:`InputError` for a scenario the program
    refuses."""
    if not isinstance(scenario, Scenario):
        scenario = load_scenario(scenario)
    columns, summary = _native.simulate(scenario)
    return Trace(columns=dict(columns), summary=json.loads(summary))


def load_plant(path: PathLike) -> PlantFile:
    """A plant file (``softjoint identify joint`` writes one)."""
    return PlantFile.load(os.fspath(path))


@dataclass(frozen=True)
class Gains:
    """Controller gains as a gains file's ``[controller]`` table."""

    kp_v_per_deg: Sequence[float]
    ki_v_per_deg_s: float = 0.0
    integral_limit_v: float = 1.0
    v_offset_v: float = 1.7

    @staticmethod
    def candidate(plant: PlantFile, index: int, seed: int = 1,
                  search_v_offset: bool = False) -> "Gains":
        """Candidate ``index`` of ``softjoint tune``'s seeded sequence
        (0: the paper's gains)."""
        kp, ki, lim, off = _native.candidate_gains(plant, index, seed, search_v_offset)
        return Gains(list(kp), ki, lim, off)


def tune_cost(plant: PlantFile, gains: Optional[Gains] = None, plant_index: int = 0,
              plants: int = 1, seed: int = 1) -> dict:
    """The cost of one run of ``softjoint tune``'s step test with
    ``gains`` (default: the paper's) on plant ``plant_index`` of the
    ``plants`` a search with ``seed`` draws (0: the identified plant), as
    the gains file's ``RunCost`` fields (``cost``, ``settling_s``,
    ``overshoot_deg``, …)."""
    g = gains if gains is not None else Gains.candidate(plant, 0, seed)
    text = _native.tune_cost(plant, list(g.kp_v_per_deg), g.ki_v_per_deg_s,
                             g.integral_limit_v, g.v_offset_v, plant_index, plants, seed)
    return json.loads(text)


def tune(plant: PlantFile, candidates: int, plants: int, seed: int = 1,
         search_v_offset: bool = False, unit: int = TUNE_UNIT_CANDIDATES) -> dict:
    """``softjoint tune`` in this process, unit after unit: the same units
    and reduction the Ray driver runs. Returns ``gains`` (the gains file
    as a dict), ``failed_candidates``, ``rejected_early`` and
    ``heldout_beats_or_ties_paper``."""
    sweep = TuneSweep(plant, candidates, plants, seed, search_v_offset)
    results = [sweep.run_unit(*u) for u in sweep.units(unit)]
    return json.loads(sweep.reduce(results))


@dataclass(frozen=True)
class Identification:
    """What ``softjoint identify joint`` gives: ``report``, its ``--json``
    report as a dict (every plane's estimates with their 1σ, stages,
    held-out validation and verdict); ``plant``, the identified plant file
    (the text ``-o`` writes, header and ``[[uncertainty]]`` included);
    ``verified``, whether every plane passed its checks against the
    data (``report["unverified_because"]`` says why not)."""

    report: dict
    plant: PlantFile
    verified: bool


def identify_joint(log: PathLike, prior: Optional[PathLike] = None, fit_fraction: float = 0.75,
                   max_iterations: int = 100, angles: str = "camera",
                   output: Optional[PathLike] = None, allow_unverified: bool = False,
                   fits=None) -> Identification:
    """``softjoint identify joint LOG [--prior PLANT] [--fit-fraction F]
    [--max-iterations N] [--angles camera|board-estimate] [-o OUTPUT]
    --json``: the joint's plant fitted to an excitation log. With
    ``output``, the plant file is written there as the program writes it
    (atomically; also when unverified, as the program does). An unverified
    plant raises :class:`UnverifiedError` (its ``.identification`` holds
    the result) unless ``allow_unverified``, as the program exits 1.
    ``fits`` runs the mechanics stage's starts elsewhere
    (:func:`softjoint.ray_sweep.identify_joint` passes the cluster's);
    the result is the same."""
    if angles not in ("camera", "board-estimate"):
        raise InputError(f"angles {angles!r}: give \"camera\" or \"board-estimate\"")
    log_text = _read(Path(log))
    prior_text = None if prior is None else _read(Path(prior))
    prior_name = "prior" if prior is None else os.fspath(prior)
    out = None if output is None else os.fspath(output)
    report, plant_text, verified = _native.identify_joint(
        log_text, os.fspath(log), prior_text, prior_name, angles == "board-estimate",
        fit_fraction, max_iterations, out, fits)
    plant = PlantFile.from_text(plant_text, out or f"{os.fspath(log)} (identified)")
    if out is not None:
        plant.save(out)
    result = Identification(json.loads(report), plant, verified)
    if not verified and not allow_unverified:
        e = UnverifiedError(
            "the identified plant is UNVERIFIED: " + "; ".join(result.report["unverified_because"])
            + "; pass allow_unverified=True to get it with that mark")
        e.identification = result
        raise e
    return result


def write_gains(path: PathLike, gains: dict) -> None:
    """Writes a gains file (``gains``: a gains file's table, as
    :func:`tune` and ``ray_sweep.tune`` return it under ``gains``) as
    ``softjoint tune -o`` writes one, checked as a scenario or the console
    loads it (:class:`InputError` names the file and field), atomically."""
    _native.write_gains(os.fspath(path), json.dumps(gains))


def _read(path: Path) -> str:
    try:
        return path.read_text(encoding="utf-8")
    except OSError as e:
        raise InputError(f"cannot read {path}: {e}") from e


def rheology_problem(scenario: Optional[PathLike] = None, measured: Optional[PathLike] = None,
                     params: int = 4) -> RheologyProblem:
    """The problem of ``softjoint rheology calibrate [SCENARIO]
    [--measured DIR] --params N``: the scenario file (default: the
    built-in one) against the measured push in ``measured`` (its
    ``surface_points.csv`` and ``forces.csv``), or, without one, against
    the reference block pushed and recorded as the scenario says."""
    text = None if scenario is None else _read(Path(scenario))
    m = None
    if measured is not None:
        d = Path(measured)
        m = (_read(d / "surface_points.csv"), _read(d / "forces.csv"))
    name = "scenario" if scenario is None else os.fspath(scenario)
    return RheologyProblem(text, m, params, name)


@dataclass(frozen=True)
class ContourFrame:
    """One fitted frame: the fitted contour at ``samples`` points (``x``,
    ``y``; for the signature and surface models also ``angle_rad`` and
    ``radius``, else ``None``) and the frame's figures and checks
    (``figures``: the frame's entry of fit.json's ``per_frame``, with
    ``checks``)."""

    frame: float
    x: np.ndarray
    y: np.ndarray
    angle_rad: Optional[np.ndarray]
    radius: Optional[np.ndarray]
    figures: dict = field(repr=False)

    @property
    def verified(self) -> bool:
        return self.figures["checks"]["status"] == "verified"


@dataclass(frozen=True)
class ContourFit:
    """A contour fit: ``summary`` holds fit.json's fields (``status``,
    ``unverified_frames``, ``model``, ``knots``, ``surface_lambda`` …,
    ``per_frame``), ``frames`` the fitted frames."""

    summary: dict = field(repr=False)
    frames: List[ContourFrame]

    @property
    def verified(self) -> bool:
        """Whether every frame passed the fit's own checks."""
        return self.summary["status"] == "verified"


def contour_fit(points: PathLike, model: Optional[str] = None, knots: Optional[int] = None,
                time_knots: Optional[int] = None, lambda_: Optional[float] = None,
                solver: str = "reduced", samples: int = 200, signed_radii: bool = False,
                allow_unverified: bool = False) -> ContourFit:
    """Fits the contour points in the CSV ``points`` as ``softjoint
    contour fit`` does (``model``: ``"signature"``, ``"curve"`` or
    ``"surface"``, default from the data; ``lambda_``: λ, or ``None`` to
    choose it by GCV as ``--lambda gcv``).

    Raises :class:`UnverifiedError` (its ``fit`` attribute holds the
    :class:`ContourFit`) when a frame failed the fit's own checks, as the
    program exits 1, unless ``allow_unverified``; the fit then still says
    ``verified == False``. :class:`InputError` for a file, column or
    option the program refuses."""
    path = Path(points)
    text, frames = _native.contour_fit(_read(path), os.fspath(path), model, knots, time_knots,
                                       lambda_, solver, samples, signed_radii)
    summary = json.loads(text)
    fit = ContourFit(summary=summary, frames=[
        ContourFrame(f, x, y, a, r, figures)
        for (f, x, y, a, r), figures in zip(frames, summary["per_frame"])])
    if not fit.verified and not allow_unverified:
        e = UnverifiedError(
            f"{len(summary['unverified_frames'])} of {len(frames)} fitted frame(s) UNVERIFIED "
            f"(frames {summary['unverified_frames'][:10]}): their figures failed the fit's own "
            "checks (see `checks` of each frame's figures); pass allow_unverified=True to get "
            "the fit with that mark")
        e.fit = fit
        raise e
    return fit


def viscoelastic_simulate(trial: PathLike, k1_n_per_m: float, k2_n_per_m: float,
                          b_n_s_per_m: float) -> Dict[str, np.ndarray]:
    """Runs the 3-element model of seed 002 (Eq. 3: delayed spring k1,
    series spring k2, dashpot b) on the CSV ``trial`` as ``softjoint
    viscoelastic simulate`` does: on its ``time_s,displacement`` columns
    (m) to give the force (N), or else on ``time_s,force`` to give the
    displacement. Returns ``time_s``, ``displacement`` and ``force``, the
    program's CSV columns, as NumPy arrays.

    Raises :class:`InputError` for a parameter, file or column the
    program refuses (named), :class:`NonFiniteError` for a trace that
    is not finite."""
    path = Path(trial)
    t, x, f = _native.viscoelastic_simulate(_read(path), k1_n_per_m, k2_n_per_m, b_n_s_per_m,
                                            os.fspath(path))
    return {"time_s": t, "displacement": x, "force": f}


@dataclass(frozen=True)
class RopeRun:
    """A rope run: ``time_s`` (frames), ``nodes_m`` of shape (frames,
    nodes, 3) — rope_nodes.csv's positions — and ``summary``, the
    ``--json`` summary's ``status``, self-``checks``, figures and
    ``topology`` checks (without ``step_time_us`` and the file names)."""

    time_s: np.ndarray
    nodes_m: np.ndarray
    summary: dict = field(repr=False)

    @property
    def verified(self) -> bool:
        """Whether the run passed every one of its own checks."""
        return self.summary["status"] == "verified"


def rope_simulate(scenario: Optional[PathLike] = None, check_step: bool = False,
                  allow_unverified: bool = False) -> RopeRun:
    """Runs a rope scenario file (TOML; default: the built-in overhand
    knot, ``scenarios/dlo/overhand.toml``) as ``softjoint dlo rope``
    does (``check_step``: as ``--check-step``, again at half the time
    step for the ``time_step`` check).

    Raises :class:`UnverifiedError` (its ``run`` attribute holds the
    :class:`RopeRun`) when the run failed its own checks — a run the
    step's checks stopped fails ``stability`` — as the program exits 1,
    unless ``allow_unverified``. :class:`InputError` for a scenario the
    program refuses (the file and field named)."""
    if scenario is None:
        text, name = None, "built-in overhand scenario"
    else:
        path = Path(scenario)
        text, name = _read(path), os.fspath(path)
    summary, t, flat = _native.rope_simulate(text, name, check_step)
    summary = json.loads(summary)
    run = RopeRun(time_s=t, nodes_m=flat.reshape(len(t), summary["nodes"], 3), summary=summary)
    if not run.verified and not allow_unverified:
        e = UnverifiedError(
            f"{name}: UNVERIFIED: the run fails {', '.join(summary['failed_checks'])} (see "
            "`checks` in its summary); pass allow_unverified=True to get the run with that mark")
        e.run = run
        raise e
    return run


@dataclass(frozen=True)
class ViscoelasticFit:
    """A fit of the 3-element model: ``summary`` holds ``softjoint
    viscoelastic fit --json``'s fields (``k1_n_per_m``, ``k2_n_per_m``,
    ``b_n_s_per_m``, ``rms_residual_n``, ``weighted_cost_n2``,
    ``uncertainty_factor``, ``evaluations``, ``weighting``, ``samples``),
    ``fitted_force_n`` the fitted model's force at the trial's samples
    (the ``--plot`` curve)."""

    summary: dict
    fitted_force_n: np.ndarray = field(repr=False)


def viscoelastic_fit(trial: PathLike, uniform: bool = False) -> ViscoelasticFit:
    """Fits (k1, k2, b) of the 3-element model to the trial CSV ``trial``
    (``time_s,displacement,force``; s, m, N) as ``softjoint viscoelastic
    fit`` does: Nelder–Mead with the seed's weighting (tail ×100, 3
    points around the peak ×1000), or every sample alike if ``uniform``.

    Raises :class:`InputError` for a file, column or value the program
    refuses (named with its line), or a trial that does not determine the
    parameters."""
    path = Path(trial)
    text, fitted = _native.viscoelastic_fit(_read(path), os.fspath(path), uniform)
    return ViscoelasticFit(summary=json.loads(text), fitted_force_n=fitted)


@dataclass(frozen=True)
class DloSolution:
    """A static solve: ``summary`` holds ``softjoint dlo solve --json``'s
    fields (``model``, energies, ``status``, ``failed_checks``,
    ``checks`` …; without ``solve_s``, a timing, and the file names),
    ``shapes`` each solved shape as ``(name, l_fraction, columns)`` —
    ``name`` ``"wire"``, ``"belt"``, or ``"knot_free"``/``"one_knot"``
    of a sequence's step at end distance ``l_fraction`` (of L, else
    ``None``) — with shape.csv's columns as arrays, and ``unverified``
    why the answer is not verified (``None`` if it is)."""

    summary: dict = field(repr=False)
    shapes: List[tuple] = field(repr=False)
    unverified: Optional[str] = None

    @property
    def verified(self) -> bool:
        return self.unverified is None


def dlo_solve(problem: PathLike, allow_unverified: bool = False) -> DloSolution:
    """Solves the static wire, belt or end-distance sequence of the TOML
    problem file ``problem`` (Wakamatsu et al.) as ``softjoint dlo solve``
    does.

    Raises :class:`UnverifiedError` (its ``solution`` attribute holds the
    :class:`DloSolution`) when a shape failed its checks, as the program
    exits 1, unless ``allow_unverified``; :class:`InputError` for a file
    or field the program refuses."""
    path = Path(problem)
    text, why, shapes = _native.dlo_solve(_read(path), os.fspath(path))
    solution = DloSolution(summary=json.loads(text),
                           shapes=[(n, l, dict(c)) for n, l, c in shapes], unverified=why)
    if why is not None and not allow_unverified:
        e = UnverifiedError(f"{why}; pass allow_unverified=True to get the solution with that "
                            "mark (see `checks` in its summary)")
        e.solution = solution
        raise e
    return solution


@dataclass(frozen=True)
class ContourSynth:
    """A contour test case: ``summary`` (``case``, ``frames``,
    ``points_per_frame``, ``sigma``, ``seed``), ``data`` data.csv's
    columns and ``truth`` truth.csv's, as arrays."""

    summary: dict
    data: Dict[str, np.ndarray] = field(repr=False)
    truth: Dict[str, np.ndarray] = field(repr=False)


def contour_synth(case: str, n: int = 40, sigma: Optional[float] = None, every: int = 10,
                  angles: int = 10, seed: int = 1) -> ContourSynth:
    """The test case ``case`` of ``softjoint contour synth``: ``"rbc"``
    (Eq. 38 on an ``n`` × ``n`` grid, columns ``frame``, ``angle_rad``,
    ``radius``) or ``"movie"`` (the pulsating contour seen along
    ``angles`` rays every ``every``-th frame, columns ``frame``,
    ``centre_x``, ``centre_y``, ``angle_rad``, ``radius``), with noise
    ``sigma`` (``None``: 0.3, the paper's, or 1 px) seeded by ``seed``.

    Raises :class:`InputError` naming an argument out of its range."""
    text, data, truth = _native.contour_synth(case, n, sigma, every, angles, seed)
    return ContourSynth(summary=json.loads(text), data=dict(data), truth=dict(truth))


@dataclass(frozen=True)
class PushRun:
    """A push simulated and scored: ``summary`` holds ``softjoint push
    simulate --json``'s fields (``mean_f``, ``contour_mean_px``,
    ``f_per_frame``, ``instability`` …; without ``out``), ``frames``
    frames.csv's numeric columns as arrays and ``phase`` each frame's
    phase (``push``, ``retrieval``)."""

    summary: dict = field(repr=False)
    frames: Dict[str, np.ndarray] = field(repr=False)
    phase: List[str] = field(repr=False)


def _params_text(params) -> tuple:
    """Parameters as JSON text and a name: a dict of the eight, or a path
    to a JSON file (bare or ``calibrate``'s params.json); ``None`` stays."""
    if params is None:
        return None, "params"
    if isinstance(params, dict):
        return json.dumps(params), "params"
    path = Path(params)
    return _read(path), os.fspath(path)


def push_problem(material: str = "sponge", site: str = "middle-long",
                 video: Optional[PathLike] = None, ref_element_px: float = 8.0,
                 noise_seed: int = 1, integrator: str = "customised", mode: str = "both",
                 nx: int = 20, ny: int = 10, cell_px: float = 1.0,
                 repair: bool = True) -> PushProblem:
    """The push of ``softjoint push simulate``/``calibrate`` with the same
    options (``video``: a ``frame,force_n,x_px,y_px`` CSV instead of the
    recorded ground truth; ``repair=False`` is ``--no-repair``), prepared
    once for any number of runs (:meth:`PushProblem.simulate`,
    :meth:`PushProblem.objective`).

    Raises :class:`InputError` for an option or file the program refuses
    (named)."""
    v = None
    if video is not None:
        path = Path(video)
        v = (_read(path), os.fspath(path))
    return PushProblem(material, site, v, ref_element_px, noise_seed, integrator, mode, nx, ny,
                       cell_px, repair)


def push_simulate(problem: Optional[PushProblem] = None, params=None,
                  predicted_forces: bool = False, allow_unstable: bool = False,
                  **options) -> PushRun:
    """Runs the mass-spring model through a push and scores it frame by
    frame as ``softjoint push simulate`` does: ``problem`` (else
    :func:`push_problem` of ``options``), ``params`` a dict of the eight
    parameters or a JSON file (default: the material's seed values),
    ``predicted_forces`` to drive it by the force predictor (§V).

    Raises :class:`UnstableError` for a run that became unstable (the
    frame and cause named), as the program exits 1, unless
    ``allow_unstable`` (every frame from there on then scores 0);
    :class:`InputError` for parameters the program refuses."""
    if problem is None:
        problem = push_problem(**options)
    elif options:
        raise InputError(f"push_simulate: options {sorted(options)} are the problem's; "
                         "give them to push_problem")
    text, name = _params_text(params)
    summary, phase, frames = problem.simulate(text, name, predicted_forces)
    summary = json.loads(summary)
    if summary.get("instability") and not allow_unstable:
        raise UnstableError(f"{summary['instability']}; pass allow_unstable=True to get the run "
                            "with every frame from there on scored 0")
    return PushRun(summary=summary, frames=dict(frames), phase=list(phase))


def push_objective(problem: PushProblem, params, score: str = "f") -> float:
    """The fitness ``softjoint push calibrate --score SCORE`` maximises
    for ``params`` (a dict of the eight parameters, or a JSON file) on
    ``problem``'s push and sensed forces: μ(F) for ``"f"``, minus the
    mean contour distance in the finger's reach (px) for ``"contour"``.

    Raises :class:`NonFiniteError` when the run cannot be scored (the
    search counts such a candidate failed), :class:`InputError` for
    parameters the program refuses (the field named)."""
    text, name = _params_text(params)
    return problem.objective(text, score, name)


@dataclass(frozen=True)
class ViscoelasticObject:
    """An object run: ``summary`` the figures the program prints
    (``vertices``, ``traction_vertices``, ``trials``,
    ``estimated_vertices``, ``haptic_steps``, ``display_frames``, and the
    firmware update's largest difference from the exact reference,
    ``contact_difference_m``/``_rel`` and ``frames_difference_m``/``_rel``);
    ``haptic`` haptic.csv's columns; ``frame_time_s`` and
    ``displacement_m``/``force_n`` of shape (frames, vertices, 3),
    frames.csv's; ``fixed`` and ``damping_n_s_per_m`` per vertex,
    params.csv's."""

    summary: dict
    haptic: Dict[str, np.ndarray] = field(repr=False)
    frame_time_s: np.ndarray = field(repr=False)
    displacement_m: np.ndarray = field(repr=False)
    force_n: np.ndarray = field(repr=False)
    fixed: np.ndarray = field(repr=False)
    damping_n_s_per_m: np.ndarray = field(repr=False)


def viscoelastic_object(mesh: Optional[PathLike] = None, script: Optional[PathLike] = None,
                        duration_s: float = 1.5, probe_every: int = 10, seed: int = 1,
                        tensor: bool = False) -> ViscoelasticObject:
    """Runs ``softjoint viscoelastic object``: the DGFM of ``mesh`` (an
    OBJ in metres; default the shipped blob), its parameters estimated
    from a simulated probe campaign (every ``probe_every``-th traction
    vertex, noise seeded by ``seed``; damping tensors if ``tensor``), and
    the probe ``script`` (CSV ``time_s,vertex,fx_n,fy_n,fz_n``; default 1
    N down on the top vertex for 0.5 s) run for ``duration_s`` at 1 kHz by
    the firmware's update beside the exact reference.

    Raises :class:`InputError` for an argument out of its bounds or a
    file the program refuses (a script's event named by file and line)."""
    def text(p):
        if p is None:
            return None
        path = Path(p)
        return (_read(path), os.fspath(path))

    summary, haptic, frames, params = _native.viscoelastic_object(
        text(mesh), text(script), duration_s, probe_every, seed, tensor)
    summary = json.loads(summary)
    shape = (len(frames["time_s"]), summary["vertices"], 3)
    return ViscoelasticObject(
        summary=summary, haptic=dict(haptic), frame_time_s=frames["time_s"],
        displacement_m=frames["displacement_m"].reshape(shape),
        force_n=frames["force_n"].reshape(shape), fixed=params["fixed"].astype(bool),
        damping_n_s_per_m=params["damping_magnitude_n_s_per_m"])
