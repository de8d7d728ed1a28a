"""Static wires and belts from Python against `softjoint dlo solve`: the
same summary and checks, shape.csv's columns to its decimals, the
unverified status kept (UnverifiedError unless asked), and refused
problems named."""
import csv
import json

import numpy as np
import pytest

import softjoint
from conftest import run_cli

# The program's own fields: the solve's time and where it wrote.
PROGRAMS_OWN = ("solve_s", "csv", "picture")


def cli_solve(binary, problem, out):
    p = run_cli(binary, "dlo", "solve", problem, "--out", out, "--json", ok=False)
    summary = {k: v for k, v in json.loads(p.stdout).items() if k not in PROGRAMS_OWN}
    with open(out / "shape.csv") as f:
        rows = list(csv.DictReader(f))
    return p, summary, rows


def small(data, tmp_path, name, replace):
    text = (data / "dlo" / name).read_text()
    for a, b in replace:
        assert a in text
        text = text.replace(a, b)
    path = tmp_path / name
    path.write_text(text)
    return path


def test_a_verified_wire_is_the_programs(softjoint_bin, data, tmp_path):
    """The wire twisted by π on 24 intervals and 2 harmonics (≈ 0.1 s):
    verified, energy R_t π²/(2L), the program's summary and shape."""
    problem = small(data, tmp_path, "twist.toml",
                    [("harmonics = 4", "harmonics = 2"), ("intervals = 64", "intervals = 24")])
    p, want, rows = cli_solve(softjoint_bin, problem, tmp_path / "o")
    assert p.returncode == 0 and want["status"] == "verified"
    sol = softjoint.dlo_solve(problem)
    assert sol.verified and sol.summary == want
    assert sol.summary["energy_j"] == pytest.approx(2.3e-4 * np.pi ** 2 / (2 * 0.871), rel=1e-6)
    [(name, l, cols)] = sol.shapes
    assert (name, l) == ("wire", None) and len(cols["s_m"]) == len(rows)
    for k in ("s_m", "x_m", "y_m", "z_m", "phi_rad", "theta_rad", "psi_rad"):
        np.testing.assert_allclose(cols[k], [float(r[k]) for r in rows], rtol=0, atol=5.1e-7,
                                   err_msg=k)
    np.testing.assert_allclose(cols["strain"], [float(r["strain"]) for r in rows], rtol=5.1e-4,
                               atol=1e-300)


def test_an_unverified_belt_raises_and_carries_its_checks(softjoint_bin, data, tmp_path):
    """The paper's belt on 30 segments (≈ 0.2 s): the program exits 1 with
    UNVERIFIED (its discretisation check); Python raises UnverifiedError
    with the solution attached, and returns it marked when asked."""
    problem = small(data, tmp_path, "belt.toml", [("intervals = 120", "intervals = 30")])
    p, want, rows = cli_solve(softjoint_bin, problem, tmp_path / "o")
    assert p.returncode == 1 and want["status"] == "UNVERIFIED"
    assert want["failed_checks"] == ["discretisation"]
    with pytest.raises(softjoint.UnverifiedError, match="UNVERIFIED: the belt fails discretisation") as e:
        softjoint.dlo_solve(problem)
    assert e.value.solution.summary == want
    sol = softjoint.dlo_solve(problem, allow_unverified=True)
    assert not sol.verified and sol.summary == want
    assert sol.unverified in p.stderr
    [(name, _, cols)] = sol.shapes
    assert name == "belt" and len(cols["u_m"]) == len(rows)
    for k in rows[0]:
        np.testing.assert_allclose(cols[k], [float(r[k]) for r in rows], rtol=0, atol=5.1e-7,
                                   err_msg=k)


def test_dlo_solve_input_errors_name_the_file_and_field(softjoint_bin, data, tmp_path):
    bad = small(data, tmp_path, "twist.toml", [("intervals = 64", "intervals = 1")])
    cli = run_cli(softjoint_bin, "dlo", "solve", bad, "--out", tmp_path / "o", ok=False)
    assert cli.returncode != 0
    with pytest.raises(softjoint.InputError) as e:
        softjoint.dlo_solve(bad)
    assert str(bad) in str(e.value) and "`intervals` = 1: must be within 16..=2000" in str(e.value)
    assert str(e.value) in cli.stderr
    bad.write_text("model = \"rope\"\n")
    with pytest.raises(softjoint.InputError, match="model"):
        softjoint.dlo_solve(bad)
