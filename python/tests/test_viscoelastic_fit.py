"""The 3-element model's fit from Python against `softjoint viscoelastic
fit --json`: the same summary, number for number, for both weightings,
and refused input named."""
import json
import math

import numpy as np
import pytest

import softjoint
from conftest import run_cli


@pytest.fixture(scope="module")
def trial(tmp_path_factory):
    """A ramp-and-hold of 2 s at 500 Hz (k1 120 N/m, k2 300 N/m, b 15
    N·s/m) with a ±1 % ripple on the force, so the fit is not exact."""
    d = tmp_path_factory.mktemp("vfit")
    ramp = d / "ramp.csv"
    ramp.write_text("time_s,displacement\n" + "".join(
        f"{k / 500},{0.004 * min(k / 100, 1.0)}\n" for k in range(1001)))
    tr = softjoint.viscoelastic_simulate(ramp, 120.0, 300.0, 15.0)
    path = d / "trial.csv"
    path.write_text("time_s,displacement,force\n" + "".join(
        f"{float(t)!r},{float(u)!r},{float(f) * (1 + 0.01 * math.sin(37 * k))!r}\n"
        for k, (t, u, f) in enumerate(zip(tr["time_s"], tr["displacement"], tr["force"]))))
    return path


@pytest.mark.parametrize("uniform", [False, True])
def test_the_fit_is_the_programs(softjoint_bin, trial, uniform):
    args = ["--uniform"] if uniform else []
    want = json.loads(run_cli(softjoint_bin, "viscoelastic", "fit", trial, "--json", *args).stdout)
    fit = softjoint.viscoelastic_fit(trial, uniform=uniform)
    assert fit.summary == want
    assert fit.summary["weighting"] == ("uniform" if uniform else "seed")
    # The fitted curve is the model run with the fitted parameters.
    again = softjoint.viscoelastic_simulate(trial.with_name("ramp.csv"), want["k1_n_per_m"],
                                            want["k2_n_per_m"], want["b_n_s_per_m"])
    assert len(fit.fitted_force_n) == want["samples"] == 1001
    np.testing.assert_allclose(fit.fitted_force_n, again["force"], rtol=1e-12, atol=0)


def test_viscoelastic_fit_input_errors_name_the_file_and_column(softjoint_bin, tmp_path):
    bad = tmp_path / "bad.csv"
    bad.write_text("time_s,displacement,force\n0,0,0\n0.001,0.001,2e5\n0.002,0.001,1\n")
    cli = run_cli(softjoint_bin, "viscoelastic", "fit", bad, ok=False)
    assert cli.returncode != 0
    with pytest.raises(softjoint.InputError) as e:
        softjoint.viscoelastic_fit(bad)
    assert f"{bad}:3" in str(e.value) and "column `force`" in str(e.value)
    assert str(e.value) in cli.stderr
