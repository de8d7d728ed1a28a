"""Sweeps on a real Ray cluster: two raylets started as separate
processes (`ray start --head`, then `ray start --address`), one CPU each.
A short tune and a short rheology calibration on it give the results of
the program run on this machine; a worker process killed mid-sweep (Ray
retries its task) changes nothing; Ctrl-C on the driver stops the
sweep (exit 130, the finished units kept)."""
import json
import os
import signal
import subprocess
import sys
import threading
import time
import tomllib

import pytest

ray = pytest.importorskip("ray", reason="the Ray stage needs `pip install ray`")

import softjoint  # noqa: E402
from softjoint import ray_sweep  # noqa: E402
from conftest import cli_json, run_cli  # noqa: E402

PLANT = "scenarios/identify/plant.toml"


@pytest.fixture(scope="module")
def cluster():
    """Two raylets as separate `ray start` processes, one CPU each."""
    with ray_sweep.LocalCluster(raylets=2, cpus=1, timeout_s=180) as c:
        assert sum(1 for n in ray.nodes() if n["Alive"]) == 2
        yield c.address


def test_a_cluster_whose_ray_start_exits_is_an_error_not_a_hang(monkeypatch):
    """A raylet that gives up at start-up ends its `ray start --block`:
    starting the cluster then tries once more and fails naming `ray start`,
    at once, instead of asking a head that is gone (a CI run hung so)."""
    started = []

    def exiting_ray_start(self, *args):
        p = subprocess.Popen(["false"], start_new_session=True)
        p.wait()
        started.append(args)
        self._procs.append(p)

    monkeypatch.setattr(ray_sweep.LocalCluster, "_start", exiting_ray_start)
    t0 = time.time()
    with pytest.raises(RuntimeError, match="`ray start` exited"):
        with ray_sweep.LocalCluster(raylets=2, cpus=1, timeout_s=30):
            pass
    assert [a[0] for a in started] == ["--head"] * ray_sweep.LocalCluster.ATTEMPTS
    assert time.time() - t0 < 10
    assert not ray.is_initialized()


_cli_tunes = {}


def cli_tune(softjoint_bin, repo, tmp_path, candidates, plants, seed):
    """The program's gains file for this search (run once per search)."""
    key = (candidates, plants, seed)
    if key not in _cli_tunes:
        out = tmp_path / f"cli-{candidates}-{plants}-{seed}.toml"
        run_cli(softjoint_bin, "tune", PLANT, "--candidates", candidates, "--plants", plants,
                "--seed", seed, "--search-v-offset", "--allow-unproven", "-o", out, cwd=repo)
        _cli_tunes[key] = tomllib.loads(out.read_text())
    return _cli_tunes[key]


def test_two_raylets_tune_as_the_program_does(cluster, softjoint_bin, repo, tmp_path):
    assert sum(1 for n in ray.nodes() if n["Alive"]) == 2
    plant = softjoint.PlantFile.from_text((repo / PLANT).read_text(), PLANT)
    seen = []
    got = ray_sweep.tune(plant, 6, 2, seed=5, search_v_offset=True,
                         on_progress=lambda done, total: seen.append((done, total)))
    assert got["gains"] == cli_tune(softjoint_bin, repo, tmp_path, 6, 2, 5)
    # Progress: one report per unit done, of the 3 units of 2 candidates.
    assert seen == [(1, 3), (2, 3), (3, 3)]


def test_the_programs_tune_with_ray_writes_the_gains_of_its_own_run(cluster, softjoint_bin, repo, tmp_path):
    out = tmp_path / "ray.toml"
    env = dict(os.environ, SOFTJOINT_PYTHON=sys.executable)
    p = subprocess.run([softjoint_bin, "tune", PLANT, "--candidates", "6", "--plants", "2",
                        "--seed", "5", "--search-v-offset", "--allow-unproven", "--ray", cluster,
                        "-o", str(out)], cwd=repo, env=env, capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    assert not (tmp_path / "ray.ray-units.toml").exists(), "its scratch file is removed"
    assert tomllib.loads(out.read_text()) == cli_tune(softjoint_bin, repo, tmp_path, 6, 2, 5)
    # A driver that fails (here one that only exits 1) is an error naming
    # the cluster, and nothing is written.
    bad = subprocess.run([softjoint_bin, "tune", PLANT, "--candidates", "2", "--plants", "1",
                          "--ray", cluster, "-o", str(tmp_path / "no.toml")],
                         cwd=repo, env=dict(env, SOFTJOINT_PYTHON="false"),
                         capture_output=True, text=True)
    assert bad.returncode == 1
    assert f"the sweep on Ray at {cluster} failed" in bad.stderr
    assert not (tmp_path / "no.toml").exists()


def test_two_raylets_calibrate_the_lattice_as_the_program_does(cluster, softjoint_bin, data, tmp_path):
    scen = data / "rheology/small.toml"
    cli = cli_json(softjoint_bin, "rheology", "calibrate", scen, "--evaluations", 40,
                   "--seed", 3, "--out", tmp_path / "o", "--json")
    seen = []
    got = ray_sweep.rheology_calibrate(str(scen), None, 4, "ga", 40, 3, unit=3,
                                       on_progress=lambda done, total: seen.append((done, total)))
    # Progress after every batch: rising, against the budget, ending at the
    # evaluations the summary reports.
    assert seen and all(t == 40 for _, t in seen)
    assert [d for d, _ in seen] == sorted(set(d for d, _ in seen))
    assert seen[-1][0] == got["evaluations"], (seen, got)
    for d in (cli, got):
        d.pop("elapsed_s")
        d.pop("out", None)
    assert got == cli


def unit_workers():
    """Pids of Ray workers running a tune unit now (Ray titles a worker
    process by the task it runs)."""
    ps = subprocess.run(["ps", "-eo", "pid=,args="], capture_output=True, text=True).stdout
    return [int(line.split()[0]) for line in ps.splitlines() if "ray::_tune_unit" in line]


def killing_a_worker(run, workers, poll_s=0.05):
    """Runs `run` on a thread and SIGKILLs the first Ray worker that
    `workers()` lists while it runs; returns the thread (started) and
    whether a worker was killed while `run` was still going."""
    t = threading.Thread(target=run)
    t.start()
    deadline = time.time() + 60
    while t.is_alive() and time.time() < deadline:
        pids = workers()
        if pids:
            os.kill(pids[0], signal.SIGKILL)
            return t, t.is_alive()
        time.sleep(poll_s)
    return t, False


def test_a_worker_killed_mid_sweep_changes_nothing(cluster, softjoint_bin, repo, tmp_path):
    plant = softjoint.PlantFile.from_text((repo / PLANT).read_text(), PLANT)
    result = {}
    t, killed = killing_a_worker(lambda: result.update(
        ray_sweep.tune(plant, 8, 2, seed=7, search_v_offset=True)), unit_workers)
    assert killed, "no worker was seen running a unit while the sweep went on"
    t.join(120)
    assert not t.is_alive()
    assert result["gains"] == cli_tune(softjoint_bin, repo, tmp_path, 8, 2, 7)


def wait_for_units_to_go(timeout_s=20):
    """Waits until the cluster's workers run no tune unit."""
    deadline = time.time() + timeout_s
    while unit_workers():
        assert time.time() < deadline, f"units still running {timeout_s} s on"
        time.sleep(0.2)


def check_state(state, candidates, repo):
    """A stopped search's state as `softjoint tune` writes it: whole
    units (of two candidates) scored, fewer than asked, and the best so
    far the scored candidate of lowest robust cost, with its gains."""
    assert set(state) - {"best"} == {"plant_file", "plant_fnv1a", "candidates", "plants",
                                     "seed", "search_v_offset", "scored"}
    assert state["candidates"] == candidates
    indices = [c["index"] for c in state["scored"]]
    assert indices == sorted(indices) and len(indices) < candidates
    assert all(i ^ 1 in indices for i in indices), f"a unit kept in part: {indices}"
    scored = [c for c in state["scored"] if "score" in c]
    if scored:
        best = min(scored, key=lambda c: (c["score"]["robust"], c["index"]))
        assert state["best"]["index"] == best["index"]
        assert state["best"]["robust_cost"] == best["score"]["robust"]
        plant = softjoint.load_plant(repo / state["plant_file"])
        g = softjoint.Gains.candidate(plant, best["index"], state["seed"],
                                      state["search_v_offset"])
        assert state["best"]["gains"] == {
            "kp_v_per_deg": list(g.kp_v_per_deg), "ki_v_per_deg_s": g.ki_v_per_deg_s,
            "integral_limit_v": g.integral_limit_v, "v_offset_v": g.v_offset_v}
    return indices


def test_ctrl_c_cancels_the_sweeps_tasks_and_keeps_the_finished_units(cluster, softjoint_bin, repo,
                                                                      tmp_path):
    """Ctrl-C on the driver: it exits 130, the cluster's workers stop
    running the sweep's units, and the units that finished are kept in the state file `softjoint tune` writes when
    stopped, from which the program resumes to the result of an unbroken
    search. Before, a stopped Ray sweep kept nothing."""
    state_path = tmp_path / "ray.search.toml"
    p = subprocess.Popen(
        [sys.executable, "-m", "softjoint.ray_sweep", "tune", PLANT, "--candidates", "200",
         "--plants", "2", "--seed", "5", "--search-v-offset", "--address", cluster,
         "--state", str(state_path)],
        cwd=repo, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    # The state is written as units finish: stop once the first three
    # units (candidates 0-5) are in it.
    deadline = time.time() + 120
    while not (state_path.exists()
               and {0, 1, 2, 3, 4, 5} <= {c["index"] for c in
                                          tomllib.loads(state_path.read_text())["scored"]}):
        assert time.time() < deadline and p.poll() is None, "no units finished"
        time.sleep(0.05)
    p.send_signal(signal.SIGINT)
    _, err = p.communicate(timeout=60)
    assert p.returncode == 130, err
    state = tomllib.loads(state_path.read_text())
    indices = check_state(state, 200, repo)
    assert f"search state in {state_path}" in err, err
    assert f"{len(indices)} of 200 candidates scored" in err, err
    assert f"best so far: candidate {state['best']['index']} " in err, err
    # The cluster's workers stop running the sweep's units.
    wait_for_units_to_go()
    # The program goes on from it (here to the first 6 candidates, all
    # in the state: their scores are the unbroken search's, bit for bit).
    out = tmp_path / "resumed.toml"
    run_cli(softjoint_bin, "tune", PLANT, "--candidates", 6, "--plants", 2, "--seed", 5,
            "--search-v-offset", "--allow-unproven", "--resume", state_path, "-o", out, cwd=repo)
    assert tomllib.loads(out.read_text()) == cli_tune(softjoint_bin, repo, tmp_path, 6, 2, 5)


def test_the_programs_tune_with_ray_stopped_keeps_the_finished_units(cluster, softjoint_bin, repo,
                                                                     tmp_path):
    """SIGTERM to `softjoint tune --ray` alone (not its process group):
    the program passes the stop to its driver, which stops the sweep
    and hands back the units that finished; the program writes them as
    its search state and exits 143. Before, the driver never heard of
    the signal and ran the whole sweep, and the state kept nothing."""
    wait_for_units_to_go()
    out = tmp_path / "g.toml"
    env = dict(os.environ, SOFTJOINT_PYTHON=sys.executable)
    p = subprocess.Popen([softjoint_bin, "tune", PLANT, "--candidates", "400", "--plants", "2",
                          "--seed", "5", "--search-v-offset", "--ray", cluster, "-o", str(out)],
                         cwd=repo, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                         text=True)
    deadline = time.time() + 60
    while not unit_workers():
        assert time.time() < deadline and p.poll() is None, "no unit started"
        time.sleep(0.05)
    time.sleep(1.5)
    p.send_signal(signal.SIGTERM)
    # 400 candidates on two workers take minutes; a stop, seconds.
    _, err = p.communicate(timeout=60)
    assert p.returncode == 143, err
    state_path = tmp_path / "g.search.toml"
    state = tomllib.loads(state_path.read_text())
    indices = check_state(state, 400, repo)
    assert f"{len(indices)} of 400 candidates scored" in err, err
    assert not out.exists() and not (tmp_path / "g.ray-units.toml").exists()
    wait_for_units_to_go()


# `softjoint rheology calibrate --ray`: the program's search with its
# batches scored on the cluster by `ray_sweep rheology-serve`.

SMALL = "scenarios/rheology/small.toml"
# A GA of two generations of the small scenario's 8 individuals.
CALIBRATION = ["--method", "ga", "--evaluations", "16", "--seed", "4"]


def without_times(v):
    """A calibration's JSON summary without its wall times (`elapsed_s`,
    at every depth) and its output directory."""
    if isinstance(v, dict):
        return {k: without_times(x) for k, x in v.items() if k not in ("elapsed_s", "out")}
    if isinstance(v, list):
        return [without_times(x) for x in v]
    return v


def calibration_files(out):
    """What a calibration writes to `out`, as bytes, `generations.csv`
    without its wall-time column (the last)."""
    files = {f: (out / f).read_bytes() for f in
             ("params.toml", "s_per_generation.svg", "force.svg", "sections.svg")}
    rows = (out / "generations.csv").read_text().splitlines()
    assert rows[0].endswith(",elapsed_s")
    files["generations.csv"] = [r.rsplit(",", 1)[0] for r in rows]
    return files


_local = {}


def local_calibration(softjoint_bin, repo, tmp_path):
    """The program's calibration (CALIBRATION) on this machine: its
    summary and files (run once)."""
    if not _local:
        out = tmp_path / "local"
        summary = cli_json(softjoint_bin, "rheology", "calibrate", SMALL, *CALIBRATION,
                           "--out", out, "--json", cwd=repo)
        _local.update(summary=without_times(summary), files=calibration_files(out))
    return _local


def test_the_programs_calibration_with_ray_writes_the_files_of_its_own_run(cluster, softjoint_bin,
                                                                          repo, tmp_path):
    """The files (params, charts, generations but for their wall times)
    and the summary of `rheology calibrate --ray` are those of the same
    calibration without it, byte for byte."""
    out = tmp_path / "ray"
    env = dict(os.environ, SOFTJOINT_PYTHON=sys.executable)
    p = subprocess.run([softjoint_bin, "rheology", "calibrate", SMALL, *CALIBRATION, "--ray",
                        cluster, "--out", str(out), "--json"], cwd=repo, env=env,
                       capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    local = local_calibration(softjoint_bin, repo, tmp_path)
    assert without_times(json.loads(p.stdout)) == local["summary"]
    assert calibration_files(out) == local["files"]
    assert not (out / "params.search.toml").exists()
    # No cluster at the address: an error naming the driver and what it
    # said, at once (ray.init waited on such an address for minutes).
    nowhere = f"127.0.0.1:{ray_sweep._free_port()}"
    bad = subprocess.run([softjoint_bin, "rheology", "calibrate", SMALL, *CALIBRATION, "--ray",
                          nowhere, "--out", str(tmp_path / "bad")], cwd=repo, env=env,
                         capture_output=True, text=True, timeout=60)
    assert bad.returncode == 1, bad.stderr
    assert (f"the Ray driver ({sys.executable} -m softjoint.ray_sweep rheology-serve, cluster at "
            f"{nowhere}): it ended without answering a batch of 8 (exit status: 1); it said: "
            f"ConnectionError: no Ray cluster at {nowhere}") in bad.stderr, bad.stderr
    assert not (tmp_path / "bad" / "params.toml").exists()


# `softjoint push calibrate --ray`: the program's Algorithm 5 with each
# generation's new candidates scored on the cluster by `ray_sweep
# push-serve`. A small push (the host-tools tests' 3 x 2 mesh, 30 px
# ground-truth elements) and two generations: 20 + 15 simulations.
PUSH = ["--ref-element-px", "30", "--nx", "3", "--ny", "2", "--cell-px", "8",
        "--generations", "2", "--seed", "3"]
PUSH_FILES = ("params.json", "generations.csv", "mu_per_generation.svg", "snapshots.svg")


def test_the_programs_push_calibration_with_ray_writes_the_files_of_its_own_run(
        cluster, softjoint_bin, repo, tmp_path):
    """The files and the summary of `push calibrate --ray` are those of
    the same calibration without it, byte for byte; no cluster at the
    address is an error naming the driver."""
    env = dict(os.environ, SOFTJOINT_PYTHON=sys.executable)
    runs = {}
    for kind, extra in (("local", []), ("ray", ["--ray", cluster])):
        out = tmp_path / kind
        p = subprocess.run([softjoint_bin, "push", "calibrate", *PUSH, *extra, "--out", str(out),
                            "--json"], cwd=repo, env=env, capture_output=True, text=True)
        assert p.returncode == 0, p.stderr
        summary = json.loads(p.stdout)
        summary.pop("out")
        runs[kind] = (summary, {f: (out / f).read_bytes() for f in PUSH_FILES})
    assert runs["ray"] == runs["local"]
    assert runs["local"][0]["evaluations"] == 35
    nowhere = f"127.0.0.1:{ray_sweep._free_port()}"
    bad = subprocess.run([softjoint_bin, "push", "calibrate", *PUSH, "--ray", nowhere, "--out",
                          str(tmp_path / "bad")], cwd=repo, env=env, capture_output=True,
                         text=True, timeout=60)
    assert bad.returncode == 1, bad.stderr
    assert (f"the Ray driver ({sys.executable} -m softjoint.ray_sweep push-serve, cluster at "
            f"{nowhere}): it ended without answering a batch of 20 (exit status: 1); it said: "
            f"ConnectionError: no Ray cluster at {nowhere}") in bad.stderr, bad.stderr
    assert not (tmp_path / "bad" / "params.json").exists()


def test_push_problem_scores_a_batch_as_its_objective_does():
    """`PushProblem.scores`, what the Ray tasks run: each gene vector's
    fitness as `push_objective` gives it, NaN for one that cannot be
    scored, and a vector of the wrong length refused by its index."""
    problem = softjoint.push_problem(ref_element_px=30, nx=3, ny=2, cell_px=8)
    genes = [[0.01, 10.0, 10.0, 1.0, 1000.0, 0.5, 0.5, 0.5],
             [0.0, 100.0, 1.0, 0.0, 50.0, 0.1, 0.01, 0.9]]
    names = ["k_damping", "k_length", "k_area", "k_angle", "max_force", "max_alpha",
             "yield_strain", "creep"]
    got = problem.scores(genes, "contour")
    for g, s in zip(genes, got):
        want = softjoint.push_objective(problem, dict(zip(names, g)), "contour")
        assert s == want
    with pytest.raises(softjoint.InputError, match=r"genes\[1\]: 7 values"):
        problem.scores([genes[0], genes[1][:7]])


# Stands in for Python as $SOFTJOINT_PYTHON: runs the real driver with
# the same arguments, passes its answers on and touches TAP_DIR/answer-N
# after the N-th, and passes SIGINT on to it; exits with its status.
TAP = r'''
import os, signal, subprocess, sys, threading
child = subprocess.Popen([os.environ["TAP_PYTHON"]] + sys.argv[1:], stdout=subprocess.PIPE)
signal.signal(signal.SIGINT, lambda *_: child.send_signal(signal.SIGINT))
def answers():
    for n, line in enumerate(child.stdout, 1):
        sys.stdout.buffer.write(line)
        sys.stdout.buffer.flush()
        open(os.path.join(os.environ["TAP_DIR"], f"answer-{n}"), "w").close()
threading.Thread(target=answers, daemon=True).start()
rc = child.wait()
sys.exit(rc if rc >= 0 else 128 - rc)
'''


def tapped(args, cwd, tmp_path):
    """Starts the program (`args`, with `--ray`) with the tap standing in
    for Python: each answer line of the driver marks a file
    `answer-N` in `tmp_path`."""
    tap = tmp_path / "tap.py"
    tap.write_text(TAP)
    wrapper = tmp_path / "python"
    wrapper.write_text(f"#!/bin/sh\nexec {sys.executable} {tap} \"$@\"\n")
    wrapper.chmod(0o755)
    env = dict(os.environ, SOFTJOINT_PYTHON=str(wrapper), TAP_PYTHON=sys.executable,
               TAP_DIR=str(tmp_path))
    return subprocess.Popen([str(a) for a in args], cwd=cwd, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


def interrupted_after_one_answer(args, cwd, tmp_path):
    """Runs the program (`args`, with `--ray`) with the tap standing in
    for Python, sends SIGINT once the driver has answered its first
    batch; returns the program's exit status and standard error."""
    p = tapped(args, cwd, tmp_path)
    deadline = time.time() + 120
    while not (tmp_path / "answer-1").exists():
        assert time.time() < deadline and p.poll() is None, "no batch was answered"
        time.sleep(0.02)
    p.send_signal(signal.SIGINT)
    _, err = p.communicate(timeout=60)
    return p.returncode, err


def test_the_programs_calibration_with_ray_stopped_keeps_its_state(cluster, softjoint_bin, repo,
                                                                  tmp_path):
    """SIGINT to `rheology calibrate --ray` once its driver has answered
    a batch: exit 130, the scored batches kept in the search state (the
    batch in flight lost), from which the program goes on without --ray
    to the files of the calibration never stopped."""
    out = tmp_path / "stopped"
    rc, err = interrupted_after_one_answer(
        [softjoint_bin, "rheology", "calibrate", SMALL, "--method", "ga", "--evaluations", "400",
         "--seed", "4", "--ray", cluster, "--out", out], repo, tmp_path)
    assert rc == 130, err
    state_path = out / "params.search.toml"
    assert f"search state in {state_path}" in err, err
    state = tomllib.loads(state_path.read_text())
    # The batches answered: at least the first generation (8).
    answered = len(list(tmp_path.glob("answer-*")))
    assert state["evaluations"] >= len(state["scored"]) >= 8, (answered, state)
    assert (state["method"], state["seed"], state["params"]) == ("ga", 4, 4)
    assert not (out / "params.toml").exists()
    resumed = cli_json(softjoint_bin, "rheology", "calibrate", SMALL, *CALIBRATION, "--resume",
                       state_path, "--out", out, "--json", cwd=repo)
    # The state's scores are taken, not simulated again (the first
    # generation's at least), and the result is the unbroken search's.
    assert resumed["resumed"]["candidates_taken"] >= 8, (answered, resumed)
    assert without_times(resumed) == without_times(
        dict(local_calibration(softjoint_bin, repo, tmp_path)["summary"], resumed=resumed["resumed"]))
    assert calibration_files(out) == local_calibration(softjoint_bin, repo, tmp_path)["files"]


def test_the_programs_push_calibration_with_ray_stopped_keeps_its_state(cluster, softjoint_bin,
                                                                        repo, tmp_path):
    """SIGINT to `push calibrate --ray` once its driver has answered the
    first generation's batch: exit 130, the answered candidates kept in
    the search state (the batch in flight lost), from which the program
    goes on without --ray to the files of the calibration never stopped."""
    # Four generations: 20 candidates, then 15 new ones each.
    push = PUSH[:-4] + ["--generations", "4", "--seed", "3"]
    out = tmp_path / "stopped"
    rc, err = interrupted_after_one_answer(
        [softjoint_bin, "push", "calibrate", *push, "--ray", cluster, "--out", out], repo,
        tmp_path)
    assert rc == 130, err
    state_path = out / "params.search.toml"
    assert str(state_path) in err, err
    state = tomllib.loads(state_path.read_text())
    answered = len(list(tmp_path.glob("answer-*")))
    assert answered < 4, f"the search ran to its end ({answered} batches) before the signal"
    assert state["evaluations"] >= len(state["scored"]) >= 20, (answered, state)
    assert (state["generations"], state["seed"]) == (4, 3)
    assert "best" in state
    assert not (out / "params.json").exists()
    resumed = cli_json(softjoint_bin, "push", "calibrate", *push, "--resume", state_path,
                       "--out", out, "--json", cwd=repo)
    local = cli_json(softjoint_bin, "push", "calibrate", *push, "--out", tmp_path / "local",
                     "--json", cwd=repo)
    for s in (resumed, local):
        s.pop("out")
        s.pop("resumed", None)
    assert resumed == local
    assert (out / "params.json").read_bytes() == (tmp_path / "local" / "params.json").read_bytes()
    cut = lambda d: [r.rsplit(",", 1)[0] for r in (d / "generations.csv").read_text().splitlines()]
    assert cut(out) == cut(tmp_path / "local")


@pytest.fixture(scope="module")
def identify_log(softjoint_bin, tmp_path_factory):
    """A 240 s standard plan recorded on the default 3D joint, and the
    program's identification of it on this machine (4 iterations per
    stage: the mechanics stage still runs from five starts per plane):
    its `--json` report and plant file, the file names taken out."""
    d = tmp_path_factory.mktemp("identify")
    plan = run_cli(softjoint_bin, "identify", "plan", "--joint", "3d", "--duration-s", "240").stdout
    (d / "plan.toml").write_text(plan)
    run_cli(softjoint_bin, "sim", "--excite", d / "plan.toml", "--log", d / "log.csv")
    local = identified(run_cli(softjoint_bin, *IDENTIFY(d / "log.csv", d / "local.toml")),
                       d / "local.toml")
    starts = [st["starts"] for plane in local[0]["planes"] for st in plane["stages"]
              if st["name"] == "mechanics"]
    assert starts == [5, 5], starts
    return d / "log.csv", local


def IDENTIFY(log, out):
    return ["identify", "joint", log, "-o", out, "--max-iterations", "4", "--json",
            "--allow-unverified"]


def identified(p, plant):
    """The report and the plant file of an `identify joint --json` run."""
    report = json.loads(p.stdout)
    report.pop("plant_file")
    return report, [line for line in plant.read_text().splitlines() if not line.startswith("#")]


def identify_workers():
    ps = subprocess.run(["ps", "-eo", "pid=,args="], capture_output=True, text=True).stdout
    return [int(line.split()[0]) for line in ps.splitlines() if "ray::_identify_unit" in line]


def test_the_programs_identification_with_ray_fits_its_starts_there_and_gives_its_own_result(
        cluster, softjoint_bin, identify_log, tmp_path):
    """`identify joint --ray`: the mechanics stage's five starts of each
    plane go to the cluster as one request per plane (the tap counts the
    driver's answers), one worker fitting a start is killed (Ray runs the
    start again), and the plant file and report are the program's own
    on this machine, every 1σ and evaluation count included."""
    log, local = identify_log
    out = tmp_path / "ray.toml"
    p = tapped([softjoint_bin, *IDENTIFY(log, out), "--ray", cluster], None, tmp_path)
    killed = None
    deadline = time.time() + 120
    while killed is None and p.poll() is None and time.time() < deadline:
        pids = identify_workers()
        if pids:
            os.kill(pids[0], signal.SIGKILL)
            killed = pids[0]
        time.sleep(0.05)
    stdout, err = p.communicate(timeout=300)
    assert killed is not None, f"no worker was seen fitting a start: {err}"
    assert p.returncode == 0, err
    assert len(list(tmp_path.glob("answer-*"))) == 2, "one request per plane answered"
    assert identified(subprocess.CompletedProcess([], 0, stdout), out) == local


def heldout_workers():
    ps = subprocess.run(["ps", "-eo", "pid=,args="], capture_output=True, text=True).stdout
    return [int(line.split()[0]) for line in ps.splitlines() if "ray::_heldout_unit" in line]


def test_the_held_out_check_runs_on_ray_and_a_killed_worker_changes_nothing(
        cluster, softjoint_bin, repo, tmp_path):
    """The tuned gains' held-out check (the winner and the paper's gains
    on every held-out manoeuvre, on plants drawn anew from the plant
    file's uncertainty) as Ray tasks, one worker killed while it runs a
    manoeuvre: the check and the gains file are the ones the reduction
    makes on this machine and the program writes."""
    plant = softjoint.PlantFile.from_text((repo / PLANT).read_text(), PLANT)
    sweep = softjoint.TuneSweep(plant, 6, 2, 5, True)
    results = ray_sweep.tune_units(sweep, plant)
    got = {}
    t, killed = killing_a_worker(lambda: got.update(
        heldout=ray_sweep.tune_heldout(sweep, plant, results)), heldout_workers, poll_s=0.02)
    t.join(120)
    assert killed, "no worker was seen running a held-out unit while the check went on"
    assert len(got["heldout"]) == len(sweep.heldout_units()) == 6
    on_ray = json.loads(sweep.reduce(results, got["heldout"]))
    assert on_ray == json.loads(sweep.reduce(results))
    assert on_ray["gains"] == cli_tune(softjoint_bin, repo, tmp_path, 6, 2, 5)
    # A held-out result for another candidate than the winner is refused.
    wrong = sweep.run_heldout_unit((sweep.best_index(results) + 1) % 6, 0, 0)
    with pytest.raises(softjoint.SweepError, match="the search's winner is"):
        sweep.reduce(results, [wrong] + got["heldout"][1:])


def test_identify_joint_from_python_on_ray_is_the_programs(cluster, identify_log, tmp_path,
                                                          monkeypatch):
    """`ray_sweep.identify_joint`: the identification called from Python,
    its starts on the cluster (one request of five per plane, counted):
    the program's report and plant file."""
    log, (report, plant) = identify_log
    requests = []
    runner = ray_sweep.identify_fits

    def counted(*args, **kwargs):
        run = runner(*args, **kwargs)

        def counting(units):
            requests.append(len(units))
            return run(units)
        return counting

    monkeypatch.setattr(ray_sweep, "identify_fits", counted)
    got = ray_sweep.identify_joint(log, max_iterations=4, output=tmp_path / "py.toml",
                                   allow_unverified=True)
    got.report.pop("plant_file")
    assert got.report == report
    assert [l for l in got.plant.text.splitlines() if not l.startswith("#")] == plant
    assert requests == [5, 5]


def test_the_programs_identification_with_ray_stopped_writes_nothing(cluster, softjoint_bin,
                                                                   identify_log, tmp_path):
    """SIGINT to `identify joint --ray` once the driver has answered a
    plane's starts: the program passes the stop on to its driver and
    exits 130 saying that nothing was written (a fit keeps no state to
    resume from), and writes no plant file."""
    log, _ = identify_log
    out = tmp_path / "stopped.toml"
    rc, err = interrupted_after_one_answer(
        [softjoint_bin, *IDENTIFY(log, out), "--ray", cluster], None, tmp_path)
    assert rc == 130, err
    assert "was cut short, so nothing was written" in err, err
    assert not out.exists()
