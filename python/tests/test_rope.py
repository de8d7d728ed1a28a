"""The dynamic rope from Python against `softjoint dlo rope`: the same
summary and topology checks, the same node trajectories (rope_nodes.csv),
and refused scenarios named."""
import json
from pathlib import Path

import numpy as np
import pytest

import softjoint
from conftest import run_cli


def test_the_rope_run_is_the_programs(softjoint_bin, tmp_path):
    """The built-in overhand knot (42 s, 50 nodes, ≈ 0.6 s): the program's
    summary but its timing and file names, and rope_nodes.csv's nodes to
    its 6 decimals."""
    p = run_cli(softjoint_bin, "dlo", "rope", "--out", tmp_path / "o", "--json")
    want = {k: v for k, v in json.loads(p.stdout).items()
            if k not in ("step_time_us", "csv", "picture")}
    table = np.loadtxt(tmp_path / "o" / "rope_nodes.csv", delimiter=",", skiprows=1)
    run = softjoint.rope_simulate()
    assert run.summary == want
    assert run.verified and run.summary["checks"]["overlap"]["passed"]
    assert run.nodes_m.shape == (len(run.time_s), 50, 3)
    assert len(table) == run.nodes_m.shape[0] * 50
    np.testing.assert_allclose(np.repeat(run.time_s, 50), table[:, 0], rtol=0, atol=5e-5)
    np.testing.assert_array_equal(np.tile(np.arange(50), len(run.time_s)), table[:, 1])
    np.testing.assert_allclose(run.nodes_m.reshape(-1, 3), table[:, 2:], rtol=0, atol=5e-7)


def test_rope_input_errors_name_the_file_and_field(softjoint_bin, data, tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text((data / "dlo/overhand.toml").read_text().replace(
        "duration_s = 42.0", "duration_s = -1.0", 1))
    cli = run_cli(softjoint_bin, "dlo", "rope", bad, "--out", tmp_path / "o", ok=False)
    assert cli.returncode != 0
    with pytest.raises(softjoint.InputError) as e:
        softjoint.rope_simulate(bad)
    assert str(bad) in str(e.value) and "duration_s" in str(e.value)
    assert str(e.value) in cli.stderr


# The shipped example of a run the tool must not call right.
DRAG_THROUGH = Path(__file__).resolve().parents[2] / "scenarios" / "dlo" / "drag_through.toml"


def test_an_unverified_rope_run_raises_as_the_program_exits_1(softjoint_bin, tmp_path):
    """Issue 29: a hand drags the rope's end through the rope with the
    collision shift off; the overlap fails its check. The program exits 1
    and says UNVERIFIED; rope_simulate raises UnverifiedError with the run
    attached, and with allow_unverified returns the program's summary."""
    scenario = DRAG_THROUGH
    cli = run_cli(softjoint_bin, "dlo", "rope", scenario, "--out", tmp_path / "o", "--json",
                  ok=False)
    assert cli.returncode == 1 and "UNVERIFIED" in cli.stderr
    want = {k: v for k, v in json.loads(cli.stdout).items()
            if k not in ("step_time_us", "csv", "picture")}
    with pytest.raises(softjoint.UnverifiedError) as e:
        softjoint.rope_simulate(scenario)
    assert "overlap" in str(e.value)
    assert e.value.run.summary == want
    run = softjoint.rope_simulate(scenario, allow_unverified=True)
    assert not run.verified
    assert run.summary["failed_checks"] == ["overlap"]
    assert run.summary == want
