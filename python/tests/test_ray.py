"""Sweeps on a real Ray cluster: two raylets started as separate
processes (`ray start --head`, then `ray start --address`), one CPU each.
A short tune and a short rheology calibration on it give the results of
the program run on this machine; a worker process killed mid-sweep (Ray
retries its task) changes nothing; Ctrl-C on the driver cancels the
sweep's tasks."""
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
    got = ray_sweep.rheology_calibrate(str(scen), None, 4, "ga", 40, 3, unit=3)
    for d in (cli, got):
        d.pop("elapsed_s")
        d.pop("out", None)
    assert got == cli


def unit_workers():
    """Pids of Ray workers running a tune unit now (Ray titles a worker
    process by the task it runs)."""
    ps = subprocess.run(["ps", "-eo", "pid=,args="], capture_output=True, text=True).stdout
    return [int(line.split()[0]) for line in ps.splitlines() if "ray::_tune_unit" in line]


def test_a_worker_killed_mid_sweep_changes_nothing(cluster, softjoint_bin, repo, tmp_path):
    plant = softjoint.PlantFile.from_text((repo / PLANT).read_text(), PLANT)
    result = {}
    t = threading.Thread(target=lambda: result.update(
        ray_sweep.tune(plant, 8, 2, seed=7, search_v_offset=True)))
    t.start()
    killed = None
    deadline = time.time() + 60
    while killed is None and t.is_alive() and time.time() < deadline:
        pids = unit_workers()
        if pids:
            os.kill(pids[0], signal.SIGKILL)
            killed = pids[0]
        time.sleep(0.05)
    assert killed is not None, "no worker was seen running a unit"
    assert t.is_alive(), "the sweep was still going when its worker was killed"
    t.join(120)
    assert not t.is_alive()
    assert result["gains"] == cli_tune(softjoint_bin, repo, tmp_path, 8, 2, 7)


def test_ctrl_c_cancels_the_sweeps_tasks(cluster, repo):
    p = subprocess.Popen(
        [sys.executable, "-m", "softjoint.ray_sweep", "tune", PLANT, "--candidates", "200",
         "--plants", "2", "--seed", "1", "--address", cluster],
        cwd=repo, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 60
    while not unit_workers():
        assert time.time() < deadline and p.poll() is None, "no unit started"
        time.sleep(0.05)
    p.send_signal(signal.SIGINT)
    _, err = p.communicate(timeout=60)
    assert p.returncode == 130, err
    assert "cancelled" in err
    # The cluster's workers stop running the sweep's units.
    deadline = time.time() + 20
    while unit_workers():
        assert time.time() < deadline, "units still running 20 s after Ctrl-C"
        time.sleep(0.2)
