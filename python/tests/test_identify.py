"""Identification and files out from Python: `softjoint.identify_joint`
against `softjoint identify joint --json -o` (report and plant file byte
for byte), `PlantFile.save` and `write_gains` against the files the
program writes; refused input named."""
import json
import struct

import pytest

import softjoint
from conftest import run_cli

SCENARIO_2D = ('name = "2D"\njoint = "2d"\ntargets = [{ t_s = 0, deg = [0] }]\n'
               '[estimator]\nmethod = "paper"\n')


def record_2d(softjoint_bin, d, duration_s):
    """A standard plan of `duration_s` recorded on the default 2D joint
    into `d`/log.csv."""
    (d / "scenario.toml").write_text(SCENARIO_2D)
    plan = run_cli(softjoint_bin, "identify", "plan", "--joint", "2d", "--duration-s",
                   duration_s).stdout
    (d / "plan.toml").write_text(plan)
    run_cli(softjoint_bin, "sim", d / "scenario.toml", "--excite", d / "plan.toml", "--log",
            d / "log.csv")
    return d


@pytest.fixture(scope="module")
def log_2d(softjoint_bin, tmp_path_factory):
    """A 120 s standard plan recorded on the default 2D joint (too short
    to determine the plane: unverified)."""
    return record_2d(softjoint_bin, tmp_path_factory.mktemp("identify-2d"), 120)


def test_identify_joint_gives_the_programs_report_and_plant_file(softjoint_bin, log_2d):
    d = log_2d
    p = run_cli(softjoint_bin, "identify", "joint", d / "log.csv", "-o", d / "cli.toml", "--json",
                "--max-iterations", "5", "--allow-unverified")
    want = json.loads(p.stdout)
    got = softjoint.identify_joint(d / "log.csv", max_iterations=5, output=d / "py.toml",
                                   allow_unverified=True)
    assert want.pop("plant_file") == str(d / "cli.toml")
    assert got.report.pop("plant_file") == str(d / "py.toml")
    assert got.report == want
    assert got.verified == want["verified"]
    assert (d / "py.toml").read_bytes() == (d / "cli.toml").read_bytes()
    assert got.plant.text == (d / "cli.toml").read_text()
    # The mechanics stage ran from its starts, as in the program.
    mech = [s for s in got.report["planes"][0]["stages"] if s["name"] == "mechanics"]
    assert mech and mech[0]["starts"] >= 4
    # Unverified without the flag: UnverifiedError carrying the result,
    # as the program exits 1 (the 120 s plan's first part moves the
    # default joint too little to determine the plane).
    assert not want["verified"], want["unverified_because"]
    with pytest.raises(softjoint.UnverifiedError, match="UNVERIFIED: theta: the log determines none") as e:
        softjoint.identify_joint(d / "log.csv", max_iterations=5)
    assert e.value.identification.report["planes"] == got.report["planes"]


def test_identify_joint_refuses_bad_input_by_name(softjoint_bin, log_2d, repo):
    d = log_2d
    with pytest.raises(softjoint.InputError, match="angles 'x'"):
        softjoint.identify_joint(d / "log.csv", angles="x")
    with pytest.raises(softjoint.InputError, match="fit_fraction must be in 0.2..=1"):
        softjoint.identify_joint(d / "log.csv", fit_fraction=0.1)
    with pytest.raises(softjoint.InputError, match="max_iterations must be in 1..=1000"):
        softjoint.identify_joint(d / "log.csv", max_iterations=0)
    # A 3D plant file as the prior of a 2D log.
    plant_3d = repo / "scenarios/identify/plant.toml"
    with pytest.raises(softjoint.InputError, match="a 2D log, but .* for the other joint"):
        softjoint.identify_joint(d / "log.csv", prior=plant_3d)
    with pytest.raises(softjoint.InputError, match="nope.csv"):
        softjoint.identify_joint(d / "nope.csv")


def test_plant_files_and_gains_files_written_from_python_are_the_programs(
        softjoint_bin, repo, tmp_path):
    plant_path = str(repo / "scenarios/identify/plant.toml")
    plant = softjoint.load_plant(plant_path)
    plant.save(tmp_path / "copy.toml")
    assert (tmp_path / "copy.toml").read_text() == (repo / plant_path).read_text()
    assert softjoint.PlantFile.load(tmp_path / "copy.toml").text == plant.text
    run_cli(softjoint_bin, "tune", plant_path, "--candidates", "3", "--plants", "1", "--seed", "2",
            "--allow-unproven", "-o", tmp_path / "cli.gains.toml")
    result = softjoint.tune(plant, 3, 1, seed=2)
    softjoint.write_gains(tmp_path / "py.gains.toml", result["gains"])
    assert (tmp_path / "py.gains.toml").read_bytes() == (tmp_path / "cli.gains.toml").read_bytes()
    bad = json.loads(json.dumps(result["gains"]))
    bad["controller"]["kp_v_per_deg"][0] = -1.0
    with pytest.raises(softjoint.InputError, match=r"controller.kp_v_per_deg\[0\]"):
        softjoint.write_gains(tmp_path / "bad.toml", bad)
    assert not (tmp_path / "bad.toml").exists()


def bits(x):
    return struct.unpack("<Q", struct.pack("<d", x))[0]


def double(b):
    return struct.unpack("<d", struct.pack("<Q", b))[0]


def test_the_identification_cost_is_what_its_fits_minimise(softjoint_bin, tmp_path):
    """`IdentifyProblem.cost`: at the minimiser a start unit's fit
    reaches (A_s alone, a linear coordinate: the value is the coordinate),
    the cost is the fit's own to the bit, and no more than at the start;
    another model costs otherwise; a field that is no parameter and a
    plane the log lacks are refused by name."""
    # 240 s: the plan's pulses heat the coils and move the link.
    d = record_2d(softjoint_bin, tmp_path, 240)
    problem = softjoint.IdentifyProblem((d / "log.csv").read_text(), str(d / "log.csv"))
    field = "coil.austenite_start_c"
    unit = {"plane": 0, "start": 0, "base": [], "active": [field], "x0": [bits(60.0)],
            "fit_fraction": bits(0.75), "substep_s": bits(1e-3), "angle_sigma_deg": bits(0.1),
            "resistance_sigma_ohm": bits(0.02), "max_iterations": 20, "ftol": bits(1e-4),
            "step": bits(1e-3), "secant_updates": 2}
    fit = json.loads(problem.fit(json.dumps(unit)))["fit"]
    a_s = double(fit["x"][0])
    cost, residuals = problem.cost(0, {field: a_s})
    assert cost == double(fit["cost"])
    assert residuals > 1000
    assert problem.cost(0, {field: 60.0})[0] >= cost
    # Away from the minimiser along A_s, and with another convection, the
    # cost is higher.
    assert problem.cost(0, {field: a_s + 3.0})[0] > cost
    assert problem.cost(0, {field: a_s, "coil.convection_w_m2_k": 3 * 54.0})[0] > cost
    with pytest.raises(softjoint.InputError, match="no parameter \"coil.nope\""):
        problem.cost(0, {"coil.nope": 1.0})
    with pytest.raises(softjoint.InputError, match="plane 1 of a log with 1 plane"):
        problem.cost(1, {})
