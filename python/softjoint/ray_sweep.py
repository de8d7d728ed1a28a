"""Sweeps on a Ray cluster: the work units of ``softjoint tune`` (its
candidates, then its held-out check's Monte Carlo), of a rheology or push
calibration and of an identification's multi-starts as Ray tasks, the
reduction on the driver.

The units are the ones the one-machine program runs (``TuneSweep.units``,
``rheology_units``), each a pure function of the sweep and its index, so
the result is the one ``softjoint tune`` / ``softjoint rheology
calibrate`` gives for the same seed, bit for bit, however many workers
run them and whichever of them is lost on the way. Placement and retries
are Ray's: every task may be retried (``max_retries``) when its worker
dies; the driver only keeps at most twice the cluster's CPUs of tasks
submitted at once (see ``_gather``). For the GA each generation's population is
fanned out and the selection stays on the driver (in Rust).

Ctrl-C on the driver stops submitting the sweep's tasks and raises
:class:`SweepStopped` (a KeyboardInterrupt) with the results of the
units that had finished; the few tasks in flight (at most twice the
cluster's CPUs) end with the driver's job when it exits, or run out, one
unit each, in a session that goes on. They are not cancelled one by one:
see ``_gather``. A
tune keeps them as ``softjoint tune`` keeps a stopped search: a search
state file (``TuneSweep.write_state``: the best so far, every candidate
scored), written at the start (an empty one), as units finish (at most
once a second) and at the stop, which ``softjoint tune PLANT --resume
FILE`` goes on from; a sweep that finishes removes it. What is left
out: the units in flight at the stop are lost (at most
``TUNE_UNIT_CANDIDATES`` candidates' work each); resuming on Ray
(``--resume`` with ``--ray``) is not offered, the program resumes on this
machine.

Each worker builds a sweep's problem once (the plant's drawn plants, the
rheology measurement or the reference block's recording, seeded) and
keeps it for the sweep's next units.

Command line (what ``softjoint tune --ray ADDRESS`` runs)::

    python -m softjoint.ray_sweep tune PLANT --candidates N --plants N \\
        --seed S [--search-v-offset] --address ADDRESS [--state FILE]

and what ``softjoint rheology calibrate --ray ADDRESS`` runs, which
scores the batches the program's search sends it, one JSON line each way
(:func:`rheology_serve`)::

    python -m softjoint.ray_sweep rheology-serve [SCENARIO] [--measured DIR] \\
        --params N --address ADDRESS

and, the same way, what ``softjoint push calibrate --ray ADDRESS`` runs
(:func:`push_batches`; each line a generation's new candidates)::

    python -m softjoint.ray_sweep push-serve [--material M] [--site S] \\
        [--video CSV] [--nx N] [--ny N] ... [--score f|contour] --address ADDRESS

and what ``softjoint identify joint LOG --ray ADDRESS`` runs: each line a
request of the mechanics stage's start units (:func:`identify_serve`),
each unit fitted as a task, the answers one line back per request::

    python -m softjoint.ray_sweep identify-serve LOG [--prior PLANT] \\
        [--angles camera|board-estimate] --address ADDRESS
"""
from __future__ import annotations

import argparse
import json
import math
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple

import ray

import softjoint
from . import (
    RHEOLOGY_UNIT_CANDIDATES,
    IdentifyProblem,
    TUNE_UNIT_CANDIDATES,
    PlantFile,
    PushProblem,
    RheologyProblem,
    TuneSweep,
    load_plant,
    rheology_problem,
    rheology_units,
)

#: Retries of a task whose worker died (Ray's own mechanism).
MAX_RETRIES = 3

#: Candidates of a push calibration per task: one. A candidate is a whole
#: push simulated (seconds at the default 20 x 10 mesh), far above Ray's
#: per-task overhead, and a generation has only 15 new candidates (Table
#: III) to spread over the workers.
PUSH_UNIT_CANDIDATES = 1

# A worker's sweeps, by their specification (kept for the sweep's units).
_cache: Dict[Tuple[Any, ...], Any] = {}


def _cached(key: Tuple[Any, ...], make: Callable[[], Any]) -> Any:
    if key not in _cache:
        if len(_cache) > 8:
            _cache.clear()
        _cache[key] = make()
    return _cache[key]


@ray.remote(max_retries=MAX_RETRIES)
def _tune_unit(spec: Tuple[str, str, int, int, int, bool], unit: Tuple[int, int, int]) -> str:
    text, name, candidates, plants, seed, svo = spec
    sweep = _cached(("tune",) + spec, lambda: TuneSweep(
        PlantFile.from_text(text, name), candidates, plants, seed, svo))
    return sweep.run_unit(*unit)


@ray.remote(max_retries=MAX_RETRIES)
def _heldout_unit(spec: Tuple[str, str, int, int, int, bool], best: int,
                  unit: Tuple[int, int]) -> str:
    text, name, candidates, plants, seed, svo = spec
    sweep = _cached(("tune",) + spec, lambda: TuneSweep(
        PlantFile.from_text(text, name), candidates, plants, seed, svo))
    return sweep.run_heldout_unit(best, *unit)


@ray.remote(max_retries=MAX_RETRIES)
def _push_unit(spec: Tuple[Any, ...], score: str, genes: List[List[float]]) -> List[float]:
    problem = _cached(("push",) + spec, lambda: PushProblem(*spec))
    return problem.scores(genes, score)


@ray.remote(max_retries=MAX_RETRIES)
def _identify_unit(spec: Tuple[str, str, Optional[str], str, bool], unit: str) -> str:
    problem = _cached(("identify",) + spec, lambda: IdentifyProblem(*spec))
    return problem.fit(unit)


@ray.remote(max_retries=MAX_RETRIES)
def _rheology_unit(spec: Tuple[Optional[str], Optional[Tuple[str, str]], int, str],
                   genes: List[List[float]]) -> List[float]:
    text, measured, params, name = spec
    problem = _cached(("rheology",) + spec, lambda: RheologyProblem(text, measured, params, name))
    return problem.scores(genes)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class LocalCluster:
    """A Ray cluster of ``raylets`` raylets on this machine, each a
    ``ray start --block`` process in a process group of its own (the
    head first, the others joining it), ``cpus`` CPUs each. Used as a
    context manager; leaving it signals those process groups only (not
    ``ray stop``, which would end every Ray process of the machine)."""

    #: Attempts at starting the cluster: a raylet that gives up at start-up
    #: (its fixed wait for its agent's port file, "Timed out waiting for
    #: file …/metrics_agent_port_…", ran out beside a busy test suite on
    #: two cores: CI, session 48) ends its ``ray start``, and the cluster
    #: is then started afresh once. (A head that dies while ``ray.init``
    #: or ``ray.nodes`` is already waiting on it is not caught here.)
    ATTEMPTS = 2

    def __init__(self, raylets: int = 2, cpus: int = 1, timeout_s: float = 60.0):
        self.raylets, self.cpus, self.timeout_s = raylets, cpus, timeout_s
        self.address = f"127.0.0.1:{_free_port()}"
        self._procs: List[subprocess.Popen] = []

    def _start(self, *args: str) -> None:
        ray_bin = os.path.join(os.path.dirname(sys.executable), "ray")
        env = dict(os.environ, RAY_USAGE_STATS_ENABLED="0")
        self._procs.append(subprocess.Popen(
            [ray_bin, "start", *args, "--num-cpus", str(self.cpus), "--block",
             "--disable-usage-stats", "--dashboard-agent-listen-port", str(_free_port())],
            env=env, start_new_session=True,
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))

    def _check_started(self) -> None:
        """Raises if a ``ray start --block`` has exited: its raylet is gone,
        and asking the cluster (``ray.init``, ``ray.nodes``) would then
        wait on a head that is not there (a suite hung 13 minutes so)."""
        for p in self._procs:
            rc = p.poll()
            if rc is not None:
                raise RuntimeError(
                    f"`ray start` exited ({rc}) while the cluster at {self.address} "
                    f"was starting; Ray's logs: /tmp/ray/session_latest/logs")

    def _alive(self) -> int:
        self._check_started()
        return sum(1 for n in ray.nodes() if n["Alive"])

    def _enter_once(self) -> None:
        deadline = time.time() + self.timeout_s
        self._start("--head", "--port", self.address.split(":")[1],
                    "--include-dashboard", "false")
        while True:
            self._check_started()
            try:
                ray.init(address=self.address, log_to_driver=False)
                break
            except ConnectionError:
                if time.time() > deadline:
                    raise
                time.sleep(0.5)
        for _ in range(self.raylets - 1):
            self._start("--address", self.address)
        while self._alive() < self.raylets:
            if time.time() > deadline:
                raise TimeoutError(f"{self._alive()} of {self.raylets} raylets up "
                                   f"after {self.timeout_s} s")
            time.sleep(0.2)

    def __enter__(self) -> "LocalCluster":
        for attempt in range(self.ATTEMPTS):
            try:
                self._enter_once()
                return self
            except RuntimeError:
                self.__exit__()
                if attempt + 1 == self.ATTEMPTS:
                    raise
                self.address = f"127.0.0.1:{_free_port()}"
            except BaseException:
                self.__exit__()
                raise
        return self

    def __exit__(self, *exc: Any) -> None:
        if ray.is_initialized():
            ray.shutdown()
        for p in reversed(self._procs):
            try:
                os.killpg(p.pid, signal.SIGTERM)
            except ProcessLookupError:
                pass
        for p in self._procs:
            try:
                p.wait(timeout=1)
            except subprocess.TimeoutExpired:
                pass
            # What `ray start` left in its group (it waits tens of seconds
            # for its processes' graceful exit; the cluster is ours and
            # holds nothing to keep).
            try:
                os.killpg(p.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            p.wait()
        self._procs.clear()


def connect(address: Optional[str] = None) -> None:
    """Joins the cluster at ``address`` (``None``: ``RAY_ADDRESS`` or a
    local one) unless this process is already connected. A ``HOST:PORT``
    address that takes no TCP connection within 10 s is a ConnectionError
    naming it (``ray.init`` waited on such an address for over ten
    minutes, Ray 2.x: a program running this driver seemed to hang)."""
    if not ray.is_initialized():
        host, _, port = (address or "").rpartition(":")
        if host and "/" not in host and port.isdigit():
            try:
                socket.create_connection((host, int(port)), timeout=10).close()
            except OSError as e:
                raise ConnectionError(f"no Ray cluster at {address}: {e}") from None
        ray.init(address=address, log_to_driver=False, include_dashboard=False)


class SweepStopped(KeyboardInterrupt):
    """Ctrl-C stopped a sweep: no more of its tasks are submitted;
    ``finished`` holds the results of the units that had finished, in
    submission order, and ``units`` how many units the sweep had. A tune
    that wrote its search state sets ``state``: ``(path, candidates
    scored, best candidate's index, its robust cost)``."""

    def __init__(self, finished: list, units: int):
        super().__init__()
        self.finished, self.units = finished, units
        self.state: Optional[Tuple[str, int, Optional[int], Optional[float]]] = None


def _in_flight() -> int:
    """Tasks a sweep keeps submitted at once: twice the cluster's CPUs
    (each worker has its next task at hand), at least 2."""
    return max(2, 2 * int(ray.cluster_resources().get("CPU", 1)))


def _gather(tasks: Sequence[Callable[[], ray.ObjectRef]],
            on_done: Optional[Callable[[int, int], None]] = None,
            on_result: Optional[Callable[[list], None]] = None) -> list:
    """Submits ``tasks`` (each a call that submits one task), at most
    :func:`_in_flight` at once, and returns their results in submission
    order, each taken as its task finishes (``on_result`` is given those
    so far, in order). Ctrl-C stops submitting and raises
    :class:`SweepStopped` with the results so far; the tasks in flight
    are left to end with the driver's job (at most :func:`_in_flight`,
    one unit each).

    Why not cancel them (``ray.cancel``, as this did before): a cancel
    that meets a finishing task's reply trips a check in Ray's core
    worker ("Tried to complete task that was not pending", the race of
    ray-project/ray#54798) and the driver exits 1 instead of 130: 3 of 6
    stops 6 s into a sweep with Ray 2.60.0, 6 of 10 with the tasks
    windowed; without a cancel, 0 of 10, the workers idle within 1.3 s
    of the stop. Why a window: so that what is left running after a stop
    is a few units, not the whole sweep."""
    finished: Dict[int, Any] = {}
    running: Dict[ray.ObjectRef, int] = {}
    try:
        window, submitted = _in_flight(), 0
        while submitted < len(tasks) or running:
            while submitted < len(tasks) and len(running) < window:
                running[tasks[submitted]()] = submitted
                submitted += 1
            done, _ = ray.wait(list(running), num_returns=1)
            for r in done:
                finished[running.pop(r)] = ray.get(r)
            if on_done is not None:
                on_done(len(finished), len(tasks))
            if on_result is not None:
                on_result([finished[k] for k in sorted(finished)])
        return [finished[k] for k in range(len(tasks))]
    except KeyboardInterrupt:
        raise SweepStopped([finished[k] for k in sorted(finished)], len(tasks)) from None


class _StateWriter:
    """Writes a tune's search state (``TuneSweep.write_state``) at once
    (an empty one: a path that cannot be written is refused before the
    sweep), then as its units finish, at most once every ``every_s``
    seconds, and at a stop; ``held`` is what the last write holds."""

    def __init__(self, sweep: TuneSweep, path: str, every_s: float = 1.0):
        self.sweep, self.path, self.every_s = sweep, path, every_s
        self.held = sweep.write_state([], path)
        self.last = time.monotonic()

    def __call__(self, finished: List[str], now: bool = False) -> None:
        if now or time.monotonic() - self.last >= self.every_s:
            self.held = self.sweep.write_state(finished, self.path)
            self.last = time.monotonic()


def tune_units(sweep: TuneSweep, plant: PlantFile, address: Optional[str] = None,
               unit: int = TUNE_UNIT_CANDIDATES,
               on_progress: Optional[Callable[[int, int], None]] = None,
               on_result: Optional[Callable[[List[str]], None]] = None) -> List[str]:
    """Runs ``sweep``'s units (on ``plant``) as Ray tasks; returns their
    results for ``sweep.reduce`` or ``sweep.merge``. ``on_result`` is
    given the results finished so far as each unit finishes; Ctrl-C
    raises :class:`SweepStopped` with them."""
    connect(address)
    req = sweep.request()
    spec = ray.put((plant.text, plant.name) + tuple(req))
    tasks = [lambda u=u: _tune_unit.remote(spec, u) for u in sweep.units(unit)]
    return _gather(tasks, on_progress, on_result)


def tune_heldout(sweep: TuneSweep, plant: PlantFile, results: List[str],
                 address: Optional[str] = None) -> List[str]:
    """The held-out check of a finished search (the Monte Carlo over
    plants drawn anew from the plant file's uncertainty: the winner and
    the paper's gains on each held-out manoeuvre) as Ray tasks, one per
    manoeuvre and gains (each the search's plants' count of 25 s runs);
    returns their results for ``sweep.reduce(results, heldout)`` or
    ``sweep.merge(results, heldout)``. Ctrl-C raises
    :class:`SweepStopped` with the held-out results finished."""
    connect(address)
    best = sweep.best_index(results)
    spec = ray.put((plant.text, plant.name) + tuple(sweep.request()))
    tasks = [lambda u=u: _heldout_unit.remote(spec, best, u) for u in sweep.heldout_units()]
    return _gather(tasks)


def tune(plant: PlantFile, candidates: int, plants: int, seed: int = 1,
         search_v_offset: bool = False, address: Optional[str] = None,
         unit: int = TUNE_UNIT_CANDIDATES,
         on_progress: Optional[Callable[[int, int], None]] = None,
         state: Optional[str] = None) -> dict:
    """``softjoint tune`` with its units as Ray tasks; returns what
    ``softjoint.tune`` returns (the gains file as a dict under
    ``gains``). With ``state``, the search state (the file ``softjoint
    tune`` writes when stopped) is written there as units finish and at a
    Ctrl-C, which then raises :class:`SweepStopped`; a sweep that
    finishes removes the file it wrote (it has nothing left to resume)."""
    sweep = TuneSweep(plant, candidates, plants, seed, search_v_offset)
    writer = None if state is None else _StateWriter(sweep, state)
    results: List[str] = []
    try:
        results = tune_units(sweep, plant, address, unit, on_progress, writer)
        heldout = tune_heldout(sweep, plant, results, address)
    except SweepStopped as stopped:
        # Stopped in the held-out check: every candidate was scored; the
        # state keeps them (the program's --resume only reduces).
        if results:
            stopped.finished, stopped.units = results, len(results)
        if writer is not None:
            writer(stopped.finished, now=True)
            stopped.state = (writer.path,) + tuple(writer.held)
        raise
    if writer is not None:
        os.remove(writer.path)
    return json.loads(sweep.reduce(results, heldout))


def rheology_calibrate(scenario: Optional[str] = None, measured: Optional[str] = None,
                       params: int = 4, method: str = "ga", evaluations: int = 1000,
                       seed: int = 1, address: Optional[str] = None,
                       unit: int = RHEOLOGY_UNIT_CANDIDATES,
                       on_progress: Optional[Callable[[int, int], None]] = None) -> dict:
    """``softjoint rheology calibrate`` with each batch the search asks
    for (a GA generation, RA's probes) cut into units and run as Ray
    tasks; returns its ``--json`` summary as a dict. ``on_progress(done,
    evaluations)`` is called after each batch with the evaluations scored
    so far (the search may stop short of the budget: its summary says how
    many it made)."""
    connect(address)
    problem = rheology_problem(scenario, measured, params)
    evaluate_batch = rheology_batches(scenario, measured, params, unit)
    if on_progress is not None:
        scored = evaluate_batch
        done = 0

        def evaluate_batch(batch: List[List[float]]) -> List[float]:
            nonlocal done
            out = scored(batch)
            done += len(batch)
            on_progress(done, evaluations)
            return out

    return json.loads(problem.calibrate(method, evaluations, seed, evaluate_batch))


def rheology_batches(scenario: Optional[str] = None, measured: Optional[str] = None,
                     params: int = 4, unit: int = RHEOLOGY_UNIT_CANDIDATES
                     ) -> Callable[[List[List[float]]], List[float]]:
    """The scorer of a rheology calibration's batches on the cluster this
    process is connected to: a batch (a list of gene lists) is cut into
    units of ``unit`` gene vectors (``rheology_units``), each a
    ``_rheology_unit`` task on a worker that builds the problem of
    ``scenario``, ``measured`` and ``params`` once (as
    ``RheologyProblem.scores`` scores them: +inf for an unstable
    candidate); the scores come back in batch order. A task that failed
    for good (an InputError a worker raised, a worker lost more than
    ``MAX_RETRIES`` times) raises here; Ctrl-C raises
    :class:`SweepStopped`."""
    text = None if scenario is None else open(scenario, encoding="utf-8").read()
    m = None
    if measured is not None:
        m = tuple(open(os.path.join(measured, f), encoding="utf-8").read()
                  for f in ("surface_points.csv", "forces.csv"))
    name = "scenario" if scenario is None else os.fspath(scenario)
    spec = ray.put((text, m, params, name))

    def evaluate_batch(batch: List[List[float]]) -> List[float]:
        tasks = [lambda a=a, b=b: _rheology_unit.remote(spec, batch[a:b])
                 for a, b in rheology_units(len(batch), unit)]
        return [s for part in _gather(tasks) for s in part]

    return evaluate_batch


def push_batches(options: Dict[str, Any], score: str = "f", unit: int = PUSH_UNIT_CANDIDATES
                 ) -> Callable[[List[List[float]]], List[float]]:
    """The scorer of a push calibration's generations on the cluster this
    process is connected to: a batch (the generation's new candidates as
    gene lists of eight) is cut into units of ``unit`` candidates, each a
    ``_push_unit`` task on a worker that prepares the push of ``options``
    (:func:`softjoint.push_problem`'s keywords; ``video`` a path) once
    and scores them as ``PushProblem.scores`` does (NaN for a run that
    cannot be scored); the scores come back in batch order. A task that
    failed for good raises here; Ctrl-C raises :class:`SweepStopped`."""
    o = dict(options)
    video = o.pop("video", None)
    v = None if video is None else (open(video, encoding="utf-8").read(), os.fspath(video))
    spec = (o.get("material", "sponge"), o.get("site", "middle-long"), v,
            o.get("ref_element_px", 8.0), o.get("noise_seed", 1),
            o.get("integrator", "customised"), o.get("mode", "both"), o.get("nx", 20),
            o.get("ny", 10), o.get("cell_px", 1.0), o.get("repair", True))
    ref = ray.put(spec)

    def evaluate_batch(batch: List[List[float]]) -> List[float]:
        tasks = [lambda a=a: _push_unit.remote(ref, score, batch[a:a + unit])
                 for a in range(0, len(batch), unit)]
        return [s for part in _gather(tasks) for s in part]

    return evaluate_batch


def identify_fits(log: str, prior: Optional[str] = None, board_estimates: bool = False
                  ) -> Callable[[List[Any]], List[Any]]:
    """The runner of an identification's start units on the cluster this
    process is connected to: a request (a list of the units ``softjoint
    identify joint --ray`` sends, as parsed JSON) becomes one
    ``_identify_unit`` task per unit, on workers that read ``log`` and
    ``prior`` (paths, read here and shipped once) as the program does;
    the answers (``{"fit": ...}`` or ``{"error": ...}``) come back in
    request order. Each unit is one Levenberg-Marquardt fit, seconds to
    minutes of replays, so one unit per task. A task that failed for
    good raises here; Ctrl-C raises :class:`SweepStopped`."""
    with open(log, encoding="utf-8") as f:
        log_text = f.read()
    prior_text = None
    if prior is not None:
        with open(prior, encoding="utf-8") as f:
            prior_text = f.read()
    spec = ray.put((log_text, os.fspath(log), prior_text,
                    "prior" if prior is None else os.fspath(prior), board_estimates))

    def run(units: List[Any]) -> List[Any]:
        tasks = [lambda u=u: _identify_unit.remote(spec, json.dumps(u)) for u in units]
        return [json.loads(a) for a in _gather(tasks)]

    return run


def identify_joint(log: str, prior: Optional[str] = None, address: Optional[str] = None,
                   **options: Any) -> "softjoint.Identification":
    """:func:`softjoint.identify_joint` with the mechanics stage's starts
    as Ray tasks on the cluster at ``address`` (:func:`identify_fits`):
    the same report and plant file. ``options`` are
    :func:`softjoint.identify_joint`'s (``fit_fraction``,
    ``max_iterations``, ``angles``, ``output``, ``allow_unverified``)."""
    connect(address)
    run = identify_fits(os.fspath(log), None if prior is None else os.fspath(prior),
                        options.get("angles", "camera") == "board-estimate")

    def fits(units: List[str]) -> List[str]:
        return [json.dumps(a) for a in run([json.loads(u) for u in units])]

    return softjoint.identify_joint(log, prior, fits=fits, **options)


def identify_serve(log: str, prior: Optional[str], board_estimates: bool,
                   address: Optional[str], requests: Any, answers: Any) -> None:
    """What ``softjoint identify joint --ray ADDRESS`` runs: joins the
    cluster, then for each line of ``requests`` (``{"id": N, "units":
    [...]}``: a plane's start units) fits them on Ray
    (:func:`identify_fits`) and writes ``{"id": N, "answers": [...]}``
    to ``answers`` once they are fitted, flushed. Requests are served at
    once, each on a thread of its own (the 3D joint's two planes send
    theirs as they reach the stage), so their tasks share the cluster.
    Every number in a unit and an answer is an integer (an IEEE double's
    bits), so nothing is rounded on the way. A request whose tasks failed
    for good ends the driver (exit 1, the cause on standard error)."""
    connect(address)
    run = identify_fits(log, prior, board_estimates)
    lock = threading.Lock()

    def serve(rid: int, units: List[Any]) -> None:
        try:
            out = run(units)
        except BaseException as e:  # noqa: BLE001 - said to the program, which ends the fit
            cause = getattr(e, "cause", None) or e
            print(f"{type(cause).__name__}: {cause}", file=sys.stderr, flush=True)
            os._exit(1)
        with lock:
            answers.write(json.dumps({"id": rid, "answers": out}) + "\n")
            answers.flush()

    threads = []
    for line in requests:
        if not line.strip():
            continue
        req = json.loads(line)
        if not (isinstance(req, dict) and isinstance(req.get("id"), int)
                and isinstance(req.get("units"), list)
                and all(isinstance(u, dict) for u in req["units"])):
            raise ValueError(f"a request must be {{\"id\": N, \"units\": [...]}}, got {line[:200]!r}")
        t = threading.Thread(target=serve, args=(req["id"], req["units"]), daemon=True)
        t.start()
        threads.append(t)
    for t in threads:
        t.join()


def _batch_of(line: str) -> List[List[float]]:
    """A batch as ``rheology-serve`` reads it: a JSON array of arrays of
    finite numbers; ValueError naming what is wrong otherwise."""
    batch = json.loads(line)
    if not isinstance(batch, list) or not all(
            isinstance(g, list) and all(isinstance(x, (int, float)) and not isinstance(x, bool)
                                        and math.isfinite(x) for x in g) for g in batch):
        raise ValueError(f"a batch must be a JSON array of arrays of finite numbers, got {line[:200]!r}")
    return [[float(x) for x in g] for g in batch]


def rheology_serve(scenario: Optional[str], measured: Optional[str], params: int,
                   address: Optional[str], unit: int, batches: Any, answers: Any) -> None:
    """What ``softjoint rheology calibrate --ray ADDRESS`` runs: joins the
    cluster, then for each line of ``batches`` (a batch: a JSON array of
    gene arrays) scores it on Ray as :func:`rheology_batches` does and
    writes one line to ``answers``: a JSON array of the scores in batch
    order, ``null`` for a score that is not finite (an unstable candidate;
    the program reads it as +inf, which is how the search counts any
    non-finite S), flushed. Returns at the end of ``batches``. The search,
    its draws, its progress and its files are the program's."""
    connect(address)
    serve_batches(rheology_batches(scenario, measured, params, unit), batches, answers)


def serve_batches(evaluate_batch: Callable[[List[List[float]]], List[float]], batches: Any,
                  answers: Any) -> None:
    """For each line of ``batches`` (a JSON array of gene arrays), its
    scores by ``evaluate_batch`` as one line to ``answers``: a JSON array
    in batch order, ``null`` for a score that is not finite (the program
    reads it as its search's worst: +inf for a rheology calibration,
    which minimises, NaN, ranked last, for a push calibration, which
    maximises), flushed. Returns at the end of ``batches``."""
    for line in batches:
        if not line.strip():
            continue
        scores = evaluate_batch(_batch_of(line))
        answers.write(json.dumps([s if math.isfinite(s) else None for s in scores]) + "\n")
        answers.flush()


def _progress() -> Optional[Callable[[int, int], None]]:
    """A line on standard error, units done of all, when it is a
    terminal (as the program's progress bars)."""
    if not sys.stderr.isatty():
        return None

    def show(done: int, total: int) -> None:
        end = "\n" if done == total else ""
        print(f"\rtune on Ray: {done}/{total} units", end=end, file=sys.stderr, flush=True)

    return show


def _write_text(path: str, text: str) -> None:
    with open(path, "w", encoding="utf-8") as f:
        f.write(text)


def _kept(a: argparse.Namespace, e: KeyboardInterrupt) -> str:
    """What a stopped sweep kept, for its message."""
    if not isinstance(e, SweepStopped) or a.command != "tune":
        return ""
    units = f"; {len(e.finished)} of {e.units} units had finished"
    if a.units_out:
        return f"{units}, their candidates in {a.units_out}"
    if e.state is None:
        return units
    path, scored, index, cost = e.state
    best = ("none scored yet" if index is None else
            f"best so far: candidate {index} (robust cost {cost:.3f})")
    return (f"{units} ({scored} of {a.candidates} candidates scored), {best}; "
            f"search state in {path} (`softjoint tune {a.plant} --resume {path}` goes on "
            "from there)")


def main(argv: Optional[List[str]] = None) -> int:
    # Ctrl-C stops the sweep (below) also when this process was
    # started with SIGINT ignored, as a job a script starts in the
    # background is: Python then installs no KeyboardInterrupt handler of
    # its own, and SIGINT did nothing while the sweep ran to its end.
    signal.signal(signal.SIGINT, signal.default_int_handler)
    p = argparse.ArgumentParser(prog="python -m softjoint.ray_sweep",
                                description="softjoint sweeps on a Ray cluster")
    sub = p.add_subparsers(dest="command", required=True)
    t = sub.add_parser("tune", help="softjoint tune with its units on Ray")
    t.add_argument("plant")
    t.add_argument("--candidates", type=int, default=1000)
    t.add_argument("--plants", type=int, default=20)
    t.add_argument("--seed", type=int, default=1)
    t.add_argument("--search-v-offset", action="store_true")
    t.add_argument("--address", default=None)
    t.add_argument("--unit", type=int, default=TUNE_UNIT_CANDIDATES)
    t.add_argument("--units-out", help="write the scored candidates here (TOML) for "
                   "`softjoint tune --ray` to reduce, instead of reducing (stopped: those of "
                   "the units that finished)")
    t.add_argument("--state", default="gains.search.toml",
                   help="the search state, written as units finish and on Ctrl-C (what "
                   "`softjoint tune` writes when stopped; `softjoint tune PLANT --resume "
                   "FILE` goes on from it); removed when the sweep finishes")
    r = sub.add_parser("rheology", help="softjoint rheology calibrate with its batches on Ray")
    r.add_argument("scenario", nargs="?")
    r.add_argument("--measured")
    r.add_argument("--params", type=int, default=4)
    r.add_argument("--method", default="ga", choices=["ga", "ra", "uniform"])
    r.add_argument("--evaluations", type=int, default=1000)
    r.add_argument("--seed", type=int, default=1)
    r.add_argument("--address", default=None)
    r.add_argument("--unit", type=int, default=RHEOLOGY_UNIT_CANDIDATES)
    v = sub.add_parser("rheology-serve", help="score the batches of `softjoint rheology "
                       "calibrate --ray` on Ray: one JSON line in (a batch of gene arrays), "
                       "one JSON line out (its scores, null for +inf), until end of input")
    v.add_argument("scenario", nargs="?")
    v.add_argument("--measured")
    v.add_argument("--params", type=int, default=4)
    v.add_argument("--address", default=None)
    v.add_argument("--unit", type=int, default=RHEOLOGY_UNIT_CANDIDATES)
    u = sub.add_parser("push-serve", help="score the generations of `softjoint push calibrate "
                       "--ray` on Ray: one JSON line in (the new candidates' gene arrays), one "
                       "JSON line out (their fitness, null for one that cannot be scored), "
                       "until end of input")
    u.add_argument("--material", default="sponge")
    u.add_argument("--site", default="middle-long")
    u.add_argument("--video")
    u.add_argument("--ref-element-px", type=float, default=8.0)
    u.add_argument("--noise-seed", type=int, default=1)
    u.add_argument("--integrator", default="customised")
    u.add_argument("--mode", default="both")
    u.add_argument("--nx", type=int, default=20)
    u.add_argument("--ny", type=int, default=10)
    u.add_argument("--cell-px", type=float, default=1.0)
    u.add_argument("--no-repair", action="store_true")
    u.add_argument("--score", default="f", choices=["f", "contour"])
    u.add_argument("--address", default=None)
    u.add_argument("--unit", type=int, default=PUSH_UNIT_CANDIDATES)
    d = sub.add_parser("identify-serve", help="fit the mechanics starts of `softjoint "
                       "identify joint --ray` on Ray: one JSON line in (the start units), one "
                       "JSON line out (their fits), until end of input")
    d.add_argument("log")
    d.add_argument("--prior")
    d.add_argument("--angles", default="camera", choices=["camera", "board-estimate"])
    d.add_argument("--address", default=None)
    a = p.parse_args(argv)
    if a.command in ("rheology-serve", "push-serve", "identify-serve"):
        return _serve(a)
    try:
        if a.command == "tune" and a.units_out:
            plant = load_plant(a.plant)
            sweep = TuneSweep(plant, a.candidates, a.plants, a.seed, a.search_v_offset)
            results = []
            try:
                results = tune_units(sweep, plant, a.address, a.unit, _progress())
                heldout = tune_heldout(sweep, plant, results, a.address)
            except SweepStopped as stopped:
                # The units that finished, for the program's search state
                # (all of them when the held-out check was stopped).
                if results:
                    stopped.finished, stopped.units = results, len(results)
                _write_text(a.units_out, sweep.merge(stopped.finished))
                raise
            _write_text(a.units_out, sweep.merge(results, heldout))
            return 0
        if a.command == "tune":
            out = tune(load_plant(a.plant), a.candidates, a.plants, a.seed,
                       a.search_v_offset, a.address, a.unit, _progress(), state=a.state)
        else:
            out = rheology_calibrate(a.scenario, a.measured, a.params, a.method,
                                     a.evaluations, a.seed, a.address, a.unit)
    except KeyboardInterrupt as e:
        print(f"stopped: no more of the sweep's tasks submitted{_kept(a, e)}",
              file=sys.stderr)
        return 130
    json.dump(out, sys.stdout, indent=2, sort_keys=True)
    print()
    return 0


def _serve(a: argparse.Namespace) -> int:
    """``rheology-serve``, ``push-serve`` and ``identify-serve``: the answers go to the standard output this
    process was given, and everything else written to file descriptor 1
    (Ray's own messages, a stray print) to standard error, so that no line
    but an answer reaches the program. A failure is said on standard
    error (what a worker raised, without Ray's traceback) and exits 1;
    Ctrl-C stops submitting and exits 130."""
    answers = os.fdopen(os.dup(1), "w", encoding="utf-8")
    os.dup2(2, 1)
    sys.stdout = sys.stderr
    try:
        if a.command == "identify-serve":
            identify_serve(a.log, a.prior, a.angles == "board-estimate", a.address, sys.stdin,
                           answers)
        elif a.command == "push-serve":
            connect(a.address)
            options = dict(material=a.material, site=a.site, video=a.video,
                           ref_element_px=a.ref_element_px, noise_seed=a.noise_seed,
                           integrator=a.integrator, mode=a.mode, nx=a.nx, ny=a.ny,
                           cell_px=a.cell_px, repair=not a.no_repair)
            serve_batches(push_batches(options, a.score, a.unit), sys.stdin, answers)
        else:
            rheology_serve(a.scenario, a.measured, a.params, a.address, a.unit, sys.stdin,
                           answers)
    except KeyboardInterrupt:
        print("stopped: no more of the batch's tasks submitted", file=sys.stderr)
        return 130
    except Exception as e:  # noqa: BLE001 - said to the program, which ends the search
        cause = getattr(e, "cause", None) or e
        print(f"{type(cause).__name__}: {cause}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
