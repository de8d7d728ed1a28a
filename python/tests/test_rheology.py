"""The rheology lattice from Python against `softjoint rheology`: the
objective S of one parameter set, and a calibration, equal to the
program's."""
import pytest

import softjoint
from conftest import cli_json, run_cli

GENES = [800.0, 5000.0, 9000.0, 0.45]


@pytest.fixture(scope="session")
def measured(softjoint_bin, data, tmp_path_factory):
    """A measured push: the reference block of the small scenario, pushed
    and recorded by the program."""
    d = tmp_path_factory.mktemp("measured")
    run_cli(softjoint_bin, "rheology", "simulate", data / "rheology/small.toml",
            "--model", "reference", "--out", d, "--json")
    return d


def test_the_objective_is_the_clis_score(softjoint_bin, data, measured, tmp_path):
    params = tmp_path / "params.toml"
    params.write_text("[all]\nk_gf_per_cm2 = 800.0\nc1_gfs_per_cm2 = 5000.0\n"
                      "c2_gfs_per_cm2 = 9000.0\na = 0.45\n")
    cli = cli_json(softjoint_bin, "rheology", "simulate", data / "rheology/small.toml",
                   "--params", params, "--measured", measured, "--out", tmp_path / "o", "--json")
    problem = softjoint.rheology_problem(data / "rheology/small.toml", measured, 4)
    assert [r[0] for r in problem.ranges()] == [
        "all.k_gf_per_cm2", "all.c1_gfs_per_cm2", "all.c2_gfs_per_cm2", "all.a"]
    assert problem.objective(GENES) == cli["score"]["s"]
    assert problem.scores([GENES, GENES]) == [cli["score"]["s"]] * 2


@pytest.mark.parametrize("with_measured", [True, False])
def test_a_calibration_is_the_clis(softjoint_bin, data, measured, tmp_path, with_measured):
    scen = data / "rheology/small.toml"
    extra = ["--measured", measured] if with_measured else []
    cli = cli_json(softjoint_bin, "rheology", "calibrate", scen, *extra, "--evaluations", 30,
                   "--seed", 3, "--out", tmp_path / "o", "--json")
    problem = softjoint.rheology_problem(scen, measured if with_measured else None, 4)
    import json
    local = json.loads(problem.calibrate("ga", 30, 3))
    # A batch scored by a Python callable, unit by unit (what Ray does).
    def by_units(batch):
        return [s for a, b in softjoint.rheology_units(len(batch), 3)
                for s in problem.scores(batch[a:b])]
    called = json.loads(problem.calibrate("ga", 30, 3, by_units))
    for got in (local, called):
        for k in ("elapsed_s", "out"):
            got.pop(k, None)
        want = {k: v for k, v in cli.items() if k not in ("elapsed_s", "out")}
        assert got == want


def test_rheology_errors_are_typed(data):
    with pytest.raises(softjoint.InputError, match="4, 8 or 16"):
        softjoint.rheology_problem(data / "rheology/small.toml", None, 5)
    problem = softjoint.rheology_problem(data / "rheology/small.toml", None, 4)
    with pytest.raises(softjoint.InputError, match="expected 4 values"):
        problem.objective([1.0, 2.0])
    with pytest.raises(softjoint.InputError, match="method"):
        problem.calibrate("sa", 10, 1)
    # An exception of the batch callable stops the search and is raised.
    class Boom(Exception):
        pass
    def boom(batch):
        raise Boom("no workers")
    with pytest.raises(Boom):
        problem.calibrate("ga", 30, 1, boom)
    with pytest.raises(softjoint.SweepError, match="returned 1 scores"):
        problem.calibrate("ga", 30, 1, lambda batch: [1.0])
    with pytest.raises(softjoint.InputError, match="nope"):
        softjoint.rheology_problem(data / "nope.toml")


def test_an_unstable_lattice_is_an_unstable_error_with_the_programs_words(softjoint_bin, data, tmp_path):
    """The paper's explicit Euler at 10 ms blows the small lattice up: the
    program exits 1 naming the step and the node, the objective raises
    UnstableError with the same words, and the search's scores count it
    as +inf (an unstable candidate), not NaN."""
    scen = tmp_path / "explicit.toml"
    scen.write_text((data / "rheology/small.toml").read_text().replace(
        "[model]\ndt_ms = 10.0", "[model]\ndt_ms = 10.0\nintegrator = \"explicit_euler\"", 1))
    cli = run_cli(softjoint_bin, "rheology", "simulate", scen, "--out", tmp_path / "o", "--json",
                  ok=False)
    assert cli.returncode == 1
    said = cli.stderr.strip().splitlines()[-1]
    assert "unstable at t =" in said
    problem = softjoint.rheology_problem(scen, None, 4)
    defaults = [500.0, 2000.0, 2000.0, 0.5]  # the scenario's, the paper's defaults
    with pytest.raises(softjoint.UnstableError) as e:
        problem.objective(defaults)
    assert isinstance(e.value, softjoint.SoftjointError)
    assert str(e.value) in said
    assert problem.scores([defaults]) == [float("inf")]
