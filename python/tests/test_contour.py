"""Contour fits from Python against `softjoint contour fit`: the same
figures and checks (fit.json) and the same fitted contours (fit.csv),
the verified flag carried, and refused input named."""
import csv
import json
import math

import numpy as np
import pytest

import softjoint
from conftest import run_cli

# fit.json's fields that are the program's own (where it wrote, what).
PROGRAMS_OWN = ("units", "input", "out", "files")


def cli_fit(binary, points, out, *args):
    """The program's fit.json (it exits 1 for an unverified fit, and
    still writes it) and fit.csv's rows per frame."""
    p = run_cli(binary, "contour", "fit", points, "--out", out, "--json", *args, ok=False)
    summary = json.loads((out / "fit.json").read_text())
    rows = {}
    with open(out / "fit.csv") as f:
        for r in csv.DictReader(f):
            rows.setdefault(float(r["frame"]), []).append(r)
    return p.returncode, {k: v for k, v in summary.items() if k not in PROGRAMS_OWN}, rows


def assert_frames_equal(fit, rows, signature):
    assert [f.frame for f in fit.frames] == list(rows)
    for f in fit.frames:
        want = rows[f.frame]
        # fit.csv holds 6 decimals.
        np.testing.assert_allclose(f.x, [float(r["x"]) for r in want], rtol=0, atol=5e-7)
        np.testing.assert_allclose(f.y, [float(r["y"]) for r in want], rtol=0, atol=5e-7)
        if signature:
            np.testing.assert_allclose(f.radius, [float(r["radius"]) for r in want], atol=5e-7)
            np.testing.assert_allclose(f.angle_rad, [float(r["angle_rad"]) for r in want],
                                       atol=5e-7)
        else:
            assert f.radius is None and f.angle_rad is None


def test_a_verified_curve_fit_is_the_programs(softjoint_bin, tmp_path):
    """A closed curve through 40 points of a perturbed ellipse, λ by
    GCV: verified, with the program's figures and contour."""
    points = tmp_path / "ellipse.csv"
    t = [2 * math.pi * k / 40 for k in range(40)]
    points.write_text("x,y\n" + "".join(
        f"{30 * math.cos(a) + 0.3 * math.sin(7 * a):.6f},{18 * math.sin(a) + 0.2 * math.cos(5 * a):.6f}\n"
        for a in t))
    rc, want, rows = cli_fit(softjoint_bin, points, tmp_path / "o", "--samples", "50")
    assert rc == 0 and want["status"] == "verified"
    fit = softjoint.contour_fit(points, samples=50)
    assert fit.verified and fit.frames[0].verified
    assert fit.summary == want
    assert fit.summary["per_frame"][0]["lambda"] > 0 and fit.summary["per_frame"][0]["gcv"] > 0
    assert_frames_equal(fit, rows, signature=False)


@pytest.mark.parametrize("args,kw", [
    ((), {}),
    (("--model", "surface", "--time-knots", "10", "--knots", "10", "--lambda", "1e-3"),
     dict(model="surface", time_knots=10, knots=10, lambda_=1e-3)),
])
def test_an_unverified_fit_raises_and_carries_its_checks(softjoint_bin, tmp_path, args, kw):
    """The paper's red-blood-cell surface (Eq. 38) on a 5 × 5 grid with
    noise: the program exits 1 with frames UNVERIFIED; Python raises
    UnverifiedError with the fit attached, and returns the same fit,
    marked, when asked to."""
    run_cli(softjoint_bin, "contour", "synth", "--case", "rbc", "--n", 5, "--out", tmp_path / "s")
    points = tmp_path / "s" / "data.csv"
    rc, want, rows = cli_fit(softjoint_bin, points, tmp_path / "o", "--signed-radii",
                             "--samples", "50", *args)
    assert rc == 1 and want["status"] == "unverified" and want["unverified_frames"]
    with pytest.raises(softjoint.UnverifiedError, match="UNVERIFIED") as e:
        softjoint.contour_fit(points, signed_radii=True, samples=50, **kw)
    assert isinstance(e.value, softjoint.SoftjointError)
    fit = softjoint.contour_fit(points, signed_radii=True, samples=50, allow_unverified=True, **kw)
    assert not fit.verified and e.value.fit.summary == fit.summary == want
    bad = [f.frame for f in fit.frames if not f.verified]
    assert bad == want["unverified_frames"]
    assert all(f.figures["checks"]["status"] == "unverified" for f in fit.frames if f.frame in bad)
    assert_frames_equal(fit, rows, signature=True)


def test_contour_input_errors_name_the_file_or_field(softjoint_bin, tmp_path):
    points = tmp_path / "bad.csv"
    points.write_text("u,v\n1,2\n3,4\n5,6\n")
    cli = run_cli(softjoint_bin, "contour", "fit", points, "--out", tmp_path / "o", ok=False)
    assert cli.returncode != 0
    with pytest.raises(softjoint.InputError) as e:
        softjoint.contour_fit(points)
    assert str(points) in str(e.value) and str(e.value) in cli.stderr
    with pytest.raises(softjoint.InputError, match="model"):
        softjoint.contour_fit(points, model="spline")
    with pytest.raises(softjoint.InputError, match="lambda"):
        softjoint.contour_fit(points, lambda_=-1.0)
    with pytest.raises(softjoint.InputError, match="nope.csv"):
        softjoint.contour_fit(tmp_path / "nope.csv")
