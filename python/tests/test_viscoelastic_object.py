"""The measured-object pipeline from Python against `softjoint
viscoelastic object`: the same haptic.csv, frames.csv and params.csv
number for number (the program writes shortest round-trip numbers), the
printed figures, and refused input named. A short run (0.05 s, every
50th traction vertex probed: ≈ 0.2 s) keeps it quick."""
import re

import numpy as np
import pytest

import softjoint
from conftest import run_cli

SHORT = dict(duration_s=0.05, probe_every=50)
FLAGS = ("--duration-s", 0.05, "--probe-every", 50)


def table(path):
    with open(path) as f:
        header = f.readline().strip().split(",")
    return header, np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)


def test_the_object_run_is_the_programs(softjoint_bin, tmp_path):
    out = tmp_path / "o"
    p = run_cli(softjoint_bin, "viscoelastic", "object", *FLAGS, "--out-dir", out)
    run = softjoint.viscoelastic_object(**SHORT)
    s = run.summary
    first = re.match(r"(\d+) vertices \((\d+) traction\), (\d+) trials fitted, (\d+) vertices "
                     r"estimated; (\d+) haptic steps, (\d+) display frames", p.stdout)
    assert first, p.stdout
    assert [int(x) for x in first.groups()] == [
        s["vertices"], s["traction_vertices"], s["trials"], s["estimated_vertices"],
        s["haptic_steps"], s["display_frames"]]
    second = re.search(r"contact max \|Δu\| (\S+) m \((\S+) % of max \|u\|\), all vertices "
                       r"over the display frames (\S+) m \((\S+) %\)", p.stdout)
    assert second, p.stdout
    printed = [float(x) for x in second.groups()]
    assert printed == [float(f"{s['contact_difference_m']:.3e}"),
                       float(f"{100 * s['contact_difference_rel']:.3f}"),
                       float(f"{s['frames_difference_m']:.3e}"),
                       float(f"{100 * s['frames_difference_rel']:.3f}")]
    header, h = table(out / "haptic.csv")
    assert list(run.haptic) == sorted(header) and len(h) == s["haptic_steps"] == 50
    for k, name in enumerate(header):
        np.testing.assert_array_equal(run.haptic[name], h[:, k], err_msg=name)
    _, f = table(out / "frames.csv")
    n = s["vertices"]
    assert run.displacement_m.shape == (s["display_frames"], n, 3)
    np.testing.assert_array_equal(np.repeat(run.frame_time_s, n), f[:, 0])
    np.testing.assert_array_equal(run.displacement_m.reshape(-1, 3), f[:, 2:5])
    np.testing.assert_array_equal(run.force_n.reshape(-1, 3), f[:, 5:8])
    _, prm = table(out / "params.csv")
    np.testing.assert_array_equal(run.fixed, prm[:, 1] == 1)
    np.testing.assert_array_equal(run.damping_n_s_per_m, prm[:, 2])
    assert np.ptp(run.haptic["uz_m"]) > 0 and run.damping_n_s_per_m.max() > 0


def test_viscoelastic_object_input_errors_name_the_argument_or_line(softjoint_bin, tmp_path):
    with pytest.raises(softjoint.InputError, match=r"^probe_every must be at least 1"):
        softjoint.viscoelastic_object(probe_every=0)
    with pytest.raises(softjoint.InputError, match=r"^duration_s must be between"):
        softjoint.viscoelastic_object(duration_s=float("nan"))
    script = tmp_path / "script.csv"
    script.write_text("time_s,vertex,fx_n,fy_n,fz_n\n0,5,0,0,-1\n0.01,99999,0,0,-1\n")
    cli = run_cli(softjoint_bin, "viscoelastic", "object", *FLAGS, "--script", script,
                  "--out-dir", tmp_path / "o", ok=False)
    assert cli.returncode != 0
    with pytest.raises(softjoint.InputError) as e:
        softjoint.viscoelastic_object(script=script, **SHORT)
    assert f"{script}:3" in str(e.value) and str(e.value) in cli.stderr
