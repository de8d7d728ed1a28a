"""The joint from Python against `softjoint sim` and `softjoint tune`
run as programs: the same trace, summary, costs and tuned gains."""
import csv
import math
import tomllib

import numpy as np
import pytest

import softjoint
from conftest import cli_json, run_cli

SUMMARY_TIMES = {"wall_seconds", "realtime_factor", "trace"}


def read_csv(path):
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    head, body = rows[0], rows[1:]
    cols = {}
    for k, name in enumerate(head):
        cols[name] = np.array([float(r[k]) if r[k] != "" else math.nan for r in body])
    return cols


TWO_D = """name = "2d, camera, a step and back"
joint = "2d"
duration_s = 8.0
feedback = "camera"
[estimator]
method = "paper"
[[targets]]
t_s = 0.0
deg = [0.0]
[[targets]]
t_s = 1.0
deg = [8.0]
[[targets]]
t_s = 5.0
deg = [-3.0]
"""


@pytest.mark.parametrize("scenario", ["default", "2d"])
def test_simulate_gives_the_cli_trace_and_summary(softjoint_bin, tmp_path, scenario):
    path = None
    if scenario == "2d":
        path = tmp_path / "two_d.toml"
        path.write_text(TWO_D)
    csv_path = tmp_path / "trace.csv"
    args = ["sim"] + ([path] if path else []) + ["--csv", csv_path, "--json"]
    summary = cli_json(softjoint_bin, *args)
    trace = softjoint.simulate(path)
    ref = read_csv(csv_path)
    assert list(trace.columns) == list(ref), "the columns of the CSV, in its order"
    assert len(trace) == len(ref["t_s"]) > 1000
    for name, want in ref.items():
        got = trace[name]
        assert np.array_equal(np.isnan(got), np.isnan(want)), name
        decimals = 3 if name.startswith("v") else 4
        # The CSV rounds to its decimals; the arrays hold the values.
        bound = 0.5 * 10.0 ** -decimals * (1 + 1e-9) + 1e-12
        assert np.nanmax(np.abs(got - want)) <= bound, name
    assert trace["faults"].dtype == np.uint16
    py = {k: v for k, v in trace.summary.items() if k not in SUMMARY_TIMES}
    cli = {k: v for k, v in summary.items() if k not in SUMMARY_TIMES}
    assert py == cli


def test_a_bad_scenario_is_an_input_error_naming_the_field(softjoint_bin, tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("duration_s = -3.0\n")
    cli = run_cli(softjoint_bin, "sim", bad, "--json", ok=False)
    assert cli.returncode != 0
    with pytest.raises(softjoint.InputError) as e:
        softjoint.simulate(softjoint.load_scenario(bad))
    assert "duration_s" in str(e.value)
    # The program's own words (the last line of its message).
    assert cli.stderr.strip().splitlines()[-1].split(": ")[-1] in str(e.value)
    with pytest.raises(softjoint.InputError, match="nope.toml"):
        softjoint.load_scenario(tmp_path / "nope.toml")
    assert issubclass(softjoint.InputError, softjoint.SoftjointError)


def test_tune_cost_is_the_cli_tunes_cost_of_the_same_candidate(softjoint_bin, repo, tmp_path):
    plant_path = repo / "scenarios/identify/plant.toml"
    cli = cli_json(softjoint_bin, "tune", plant_path, "--candidates", 1, "--plants", 2,
                   "--seed", 4, "--allow-unproven", "-o", tmp_path / "g.toml", "--json")
    paper = cli["gains"]["tuning"]["paper"]
    plant = softjoint.load_plant(plant_path)
    costs = [softjoint.tune_cost(plant, None, j, 2, 4) for j in range(2)]
    assert costs[0] == paper["nominal"], "candidate 0 on the identified plant"
    c = [x["cost"] for x in costs]
    mean = sum(c) / 2
    std = math.sqrt(sum((x - mean) ** 2 for x in c) / 2)
    assert math.isclose(paper["mean"], mean, rel_tol=1e-14)
    assert math.isclose(paper["std"], std, rel_tol=1e-12, abs_tol=1e-15)
    with pytest.raises(softjoint.InputError, match="plant_index 2"):
        softjoint.tune_cost(plant, None, 2, 2, 4)
    with pytest.raises(softjoint.InputError, match="kp_v_per_deg"):
        softjoint.tune_cost(plant, softjoint.Gains([2.0, 2.0]))


def test_the_tune_sweep_gives_the_cli_gains_whatever_the_unit_size(softjoint_bin, repo, tmp_path):
    plant_path = repo / "scenarios/identify/plant.toml"
    out = tmp_path / "g.toml"
    run_cli(softjoint_bin, "tune", plant_path, "--candidates", 4, "--plants", 2, "--seed", 5,
            "--search-v-offset", "--allow-unproven", "-o", out, "--json")
    want = tomllib.loads(out.read_text())
    plant = softjoint.load_plant(plant_path)
    for unit in (1, 3):
        got = softjoint.tune(plant, 4, 2, seed=5, search_v_offset=True, unit=unit)
        assert got["gains"] == want, f"units of {unit}"


def test_a_sweep_refuses_units_that_do_not_add_up(repo):
    plant = softjoint.load_plant(repo / "scenarios/identify/plant.toml")
    sweep = softjoint.TuneSweep(plant, 3, 1, 2)
    assert sweep.units(2) == [(0, 0, 2), (1, 2, 3)]
    first = sweep.run_unit(0, 0, 2)
    with pytest.raises(softjoint.SweepError, match="candidate 2 was not scored"):
        sweep.reduce([first])
    with pytest.raises(softjoint.SweepError, match="scored twice"):
        sweep.reduce([first, first, sweep.run_unit(1, 2, 3)])
    with pytest.raises(softjoint.InputError, match="not within"):
        sweep.run_unit(1, 2, 4)
    with pytest.raises(softjoint.InputError):
        softjoint.PlantFile.from_text("[joint3d]\nbogus = 1\n", "p.toml")
