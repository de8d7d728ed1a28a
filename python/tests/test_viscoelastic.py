"""The 3-element viscoelastic model from Python against `softjoint
viscoelastic simulate`: the same trace, number for number, both ways
(displacement → force, force → displacement), and refused input named."""
import csv
import io
import math

import numpy as np
import pytest

import softjoint
from conftest import run_cli

PARAMS = (120.0, 300.0, 15.0)  # k1 N/m, k2 N/m, b N·s/m


def cli_trace(binary, trial):
    p = run_cli(binary, "viscoelastic", "simulate", trial, "--k1", PARAMS[0], "--k2", PARAMS[1],
                "--b", PARAMS[2])
    rows = list(csv.DictReader(io.StringIO(p.stdout)))
    return {k: np.array([float(r[k]) for r in rows]) for k in ("time_s", "displacement", "force")}


@pytest.mark.parametrize("given", ["displacement", "force"])
def test_the_trace_is_the_programs(softjoint_bin, tmp_path, given):
    """A ramp-and-hold of 2 s at 1 kHz: the program's CSV (shortest
    round-trip numbers) parses to exactly the arrays Python returns."""
    trial = tmp_path / "trial.csv"
    scale = 0.004 if given == "displacement" else 0.5
    trial.write_text(f"time_s,{given}\n" + "".join(
        f"{k / 1000},{scale * min(k / 300, 1.0) * (1 + 0.1 * math.sin(k / 50))}\n"
        for k in range(2001)))
    want = cli_trace(softjoint_bin, trial)
    got = softjoint.viscoelastic_simulate(trial, *PARAMS)
    for k in want:
        np.testing.assert_array_equal(got[k], want[k])
    assert np.all(np.isfinite(got["force"])) and np.ptp(got["force"]) > 0


def test_viscoelastic_input_errors_name_the_argument_or_file(softjoint_bin, tmp_path):
    trial = tmp_path / "bad.csv"
    trial.write_text("time_s,speed\n0,1\n0.001,2\n")
    cli = run_cli(softjoint_bin, "viscoelastic", "simulate", trial, "--k1", 1, "--k2", 1, "--b", 1,
                  ok=False)
    assert cli.returncode != 0
    with pytest.raises(softjoint.InputError) as e:
        softjoint.viscoelastic_simulate(trial, 1.0, 1.0, 1.0)
    assert str(trial) in str(e.value) and str(e.value) in cli.stderr
    with pytest.raises(softjoint.InputError, match="k2_n_per_m must be finite and > 0"):
        softjoint.viscoelastic_simulate(trial, 1.0, -1.0, 1.0)
