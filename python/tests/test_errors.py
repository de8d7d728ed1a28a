"""The exceptions a run can end in, raised through the public API by
inputs that honestly cause them, each checked against the program given
the same input: its class, its base `SoftjointError`, and a message that
names what went wrong. (`InputError`: test_joint.py; `UnstableError`:
test_rheology.py; `SweepError`: both.)"""
import json

import pytest

import softjoint
from conftest import run_cli

# A 2D joint with a tonne hung on it from 1 s: the plant's energy check
# stops the run at the first step of the weight (as host-tools'
# cli_long_runs test `an_unstable_plant_leaves_its_trace_up_to_the_failing_step`).
HEAVY = """joint = "2d"
duration_s = 4.0
control_period_us = 10000
[estimator]
method = "paper"
[[targets]]
t_s = 0
deg = [5.0]
[[disturbances]]
kind = "weight"
mass_g = 1e6
from_s = 1.0
to_s = 3.0
"""


def test_a_plant_that_fails_mid_run_is_a_run_cut_short_error_with_the_programs_words(
        softjoint_bin, tmp_path):
    scen = tmp_path / "heavy.toml"
    scen.write_text(HEAVY)
    cli = run_cli(softjoint_bin, "sim", scen, "--json", ok=False)
    assert cli.returncode == 1, cli.stderr
    cut = json.loads(cli.stdout)["cut_short"]
    assert cut["cause"] == "plant"
    with pytest.raises(softjoint.RunCutShortError) as e:
        softjoint.simulate(scen)
    assert isinstance(e.value, softjoint.SoftjointError)
    msg = str(e.value)
    # The step and the cause, as the program's summary gives them.
    assert f"run cut short at step {cut['at_step']} " in msg
    assert cut["reason"] in msg and "kinetic energy" in msg
    # The program's message, word for word.
    assert cli.stderr.strip().splitlines()[-1] == f"error: {msg}"


def test_an_objective_that_overflows_is_a_non_finite_error_not_an_inf(softjoint_bin, data, tmp_path):
    """A stable push scored with a shape weight of 1e308 per cm: S =
    1e308 · S_shape is past the largest double. `objective` refuses it by
    name (the output checks) instead of handing back inf; `scores`, the
    searches' form, counts it as +inf (a candidate to drop)."""
    small = data / "rheology/small.toml"
    measured = tmp_path / "measured"
    run_cli(softjoint_bin, "rheology", "simulate", small, "--model", "reference",
            "--out", measured, "--json")
    scen = tmp_path / "heavy_weight.toml"
    scen.write_text(small.read_text() + "\n[objective]\nshape_per_cm = 1e308\n")
    cli = json.loads(run_cli(softjoint_bin, "rheology", "simulate", scen, "--measured", measured,
                             "--out", tmp_path / "o", "--json").stdout)
    # The program's run of the same lattice: stable, S_shape finite, and
    # the weighted S overflows (the closed form, in Python's doubles).
    assert cli["instability"] is None
    shape_cm = cli["score"]["shape_cm"]
    assert 0.0 < shape_cm < float("inf")
    assert 1e308 * shape_cm == float("inf")
    problem = softjoint.rheology_problem(scen, measured, 4)
    defaults = [500.0, 2000.0, 2000.0, 0.5]  # the scenario's, the paper's defaults
    with pytest.raises(softjoint.NonFiniteError) as e:
        problem.objective(defaults)
    assert isinstance(e.value, softjoint.SoftjointError)
    assert "the objective S" in str(e.value) and "`inf`" in str(e.value)
    assert problem.scores([defaults]) == [float("inf")]
