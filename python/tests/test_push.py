"""The pushed block from Python against `softjoint push simulate`: the
same summary and frames.csv, the calibration's fitness equal to the
simulated μ(F) and contour distance, and refused input named. A coarse
push (30 px ground-truth elements, a 3 × 2 mesh, 8 px raster: ≈ 0.3 s a
run) keeps it short."""
import csv
import json

import numpy as np
import pytest

import softjoint
from conftest import run_cli

SMALL = dict(ref_element_px=30.0, nx=3, ny=2, cell_px=8.0)
FLAGS = ("--ref-element-px", 30, "--nx", 3, "--ny", 2, "--cell-px", 8)
# frames.csv's decimals per column.
DIGITS = dict(time_s=3, finger_depth_px=3, sensed_force_n=4, force_used_n=4, f_score=5, mean_f=5,
              contour_mean_px=3, contour_max_px=3, still_contour_mean_px=3,
              still_contour_max_px=3)


@pytest.fixture(scope="module")
def cli_run(softjoint_bin, tmp_path_factory):
    out = tmp_path_factory.mktemp("push")
    p = run_cli(softjoint_bin, "push", "simulate", *FLAGS, "--out", out, "--json")
    summary = {k: v for k, v in json.loads(p.stdout).items() if k != "out"}
    with open(out / "frames.csv") as f:
        rows = list(csv.DictReader(f))
    return summary, rows


@pytest.fixture(scope="module")
def problem():
    return softjoint.push_problem(**SMALL)


def test_the_push_is_the_programs(cli_run, problem):
    want, rows = cli_run
    run = softjoint.push_simulate(problem)
    assert run.summary == want
    assert problem.frames() == len(rows) == len(run.phase) == 100
    assert run.phase == [r["phase"] for r in rows]
    assert sorted(run.frames) == sorted(DIGITS)
    for k, digits in DIGITS.items():
        np.testing.assert_allclose(run.frames[k], [float(r[k]) for r in rows], rtol=0,
                                   atol=0.51 * 10.0 ** -digits, err_msg=k)
    np.testing.assert_array_equal(run.frames["f_score"], want["f_per_frame"])


def test_the_objective_is_the_calibrations_fitness(cli_run, problem):
    """The fitness `push calibrate` maximises: μ(F), or minus the contour
    distance, of the same run `push simulate` scores."""
    want, _ = cli_run
    params = want["params"]
    assert softjoint.push_objective(problem, params) == want["mean_f"]
    assert softjoint.push_objective(problem, params, "contour") == -want["contour_mean_px"]
    stiffer = dict(params, k_area=2 * params["k_area"])
    assert softjoint.push_objective(problem, stiffer) != want["mean_f"]


def test_push_input_errors_name_the_field(softjoint_bin, cli_run, problem, tmp_path):
    cli = run_cli(softjoint_bin, "push", "simulate", "--nx", 0, "--out", tmp_path, ok=False)
    assert cli.returncode != 0 and "--nx 0: must be 1..=2000 squares" in cli.stderr
    with pytest.raises(softjoint.InputError, match=r"^nx 0: must be 1\.\.=2000 squares"):
        softjoint.push_problem(nx=0)
    with pytest.raises(softjoint.InputError, match=r"^ref_element_px 1: must be at least 2 px"):
        softjoint.push_problem(ref_element_px=1.0)
    with pytest.raises(softjoint.InputError, match="material"):
        softjoint.push_problem(material="clay")
    bad = dict(cli_run[0]["params"], k_area=-1.0)
    params = tmp_path / "bad.json"
    params.write_text(json.dumps(bad))
    cli = run_cli(softjoint_bin, "push", "simulate", *FLAGS, "--params", params, "--out", tmp_path,
                  ok=False)
    assert cli.returncode != 0
    with pytest.raises(softjoint.InputError) as e:
        softjoint.push_objective(problem, params)
    assert "k_area" in str(e.value) and str(params) in str(e.value)
    assert str(e.value) in cli.stderr
