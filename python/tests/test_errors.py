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


def measured_small_push(softjoint_bin, data, tmp_path):
    """The small rheology scenario and a push the program made of it (the
    reference model's run, as `--measured` reads it)."""
    small = data / "rheology/small.toml"
    measured = tmp_path / "measured"
    run_cli(softjoint_bin, "rheology", "simulate", small, "--model", "reference",
            "--out", measured, "--json")
    return small, measured

def test_a_weight_for_which_the_objective_can_overflow_is_refused_by_name(softjoint_bin, data, tmp_path):
    """A shape weight of 1e308 per cm: S = 1e308 · S_shape is past the
    largest double for a stable run (issue 31: the program printed `s:
    null` and its searches counted such runs as unstable). The problem
    refuses the weight by name when it meets the measured push, as the
    program does, before any run; no inf is handed back."""
    small, measured = measured_small_push(softjoint_bin, data, tmp_path)
    scen = tmp_path / "heavy_weight.toml"
    scen.write_text(small.read_text() + "\n[objective]\nshape_per_cm = 1e308\n")
    cli = run_cli(softjoint_bin, "rheology", "simulate", scen, "--measured", measured,
                  "--out", tmp_path / "o", "--json", ok=False)
    assert cli.returncode == 1, cli.stdout
    with pytest.raises(softjoint.InputError) as e:
        softjoint.rheology_problem(scen, measured, 4)
    assert isinstance(e.value, softjoint.SoftjointError)
    msg = str(e.value)
    assert "`objective.shape_per_cm` = 1e308" in msg and "overflows" in msg
    # The program's words, after the file it names.
    assert cli.stderr.strip().splitlines()[-1] == f"error: {scen}: {msg}"

def test_a_force_term_that_overflows_in_a_batch_raises_by_name_not_inf(softjoint_bin, data, tmp_path):
    """The force term has no bound before a run: with force_per_n = 1e308
    a stable run's S overflows. A batch (the work a Ray worker does) raises
    InputError naming the weight, so the driver's search stops with it,
    instead of handing back +inf, which the search counts as an unstable
    candidate (issue 31)."""
    small, measured = measured_small_push(softjoint_bin, data, tmp_path)
    scen = tmp_path / "heavy_force.toml"
    scen.write_text(small.read_text() + "\n[objective]\nshape_per_cm = 0\nforce_per_n = 1e308\n")
    p = softjoint.rheology_problem(scen, measured, 4)
    # Points inside the ranges; the block is stable at most of them, and one
    # stable run is enough.
    batch = [[lo + f * (hi - lo) for _, lo, hi in p.ranges()] for f in (0.25, 0.5, 0.75)]
    with pytest.raises(softjoint.InputError) as e:
        p.scores(batch)
    msg = str(e.value)
    assert "`objective.force_per_n`" in msg and "S_force" in msg and "stable" in msg
