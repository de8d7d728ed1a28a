"""The contour test cases from Python against `softjoint contour synth`:
the same figures, and data.csv and truth.csv to their decimals, for both
cases; refused arguments named."""
import csv
import json

import numpy as np
import pytest

import softjoint
from conftest import run_cli

# The figures of the program's summary (the rest says where it wrote what).
FIGURES = ("case", "frames", "points_per_frame", "sigma", "seed")


def columns(path):
    with open(path) as f:
        rows = list(csv.DictReader(f))
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}


@pytest.mark.parametrize("case,args,kw,decimals", [
    ("rbc", ("--n", 6, "--seed", 3), dict(n=6, seed=3), (9, 9)),
    ("movie", ("--every", 25, "--angles", 8, "--sigma", 0.5),
     dict(every=25, angles=8, sigma=0.5), (4, 4)),
])
def test_the_case_is_the_programs(softjoint_bin, tmp_path, case, args, kw, decimals):
    out = tmp_path / case
    p = run_cli(softjoint_bin, "contour", "synth", "--case", case, *args, "--out", out, "--json")
    want = {k: v for k, v in json.loads(p.stdout).items() if k in FIGURES}
    synth = softjoint.contour_synth(case, **kw)
    assert synth.summary == want
    for got, path, digits in ((synth.data, out / "data.csv", decimals[0]),
                              (synth.truth, out / "truth.csv", decimals[1])):
        table = columns(path)
        assert list(got) == sorted(table)
        for k, v in table.items():
            # The CSV rounds to `digits` decimals (the frame number is exact).
            np.testing.assert_allclose(got[k], v, rtol=0, atol=0.51 * 10.0 ** -digits, err_msg=k)


def test_contour_synth_arguments_are_named(softjoint_bin, tmp_path):
    cli = run_cli(softjoint_bin, "contour", "synth", "--case", "rbc", "--n", 1, "--out", tmp_path,
                  ok=False)
    assert cli.returncode != 0 and "--n must be 2..=1000" in cli.stderr
    with pytest.raises(softjoint.InputError, match=r"^n must be 2\.\.=1000"):
        softjoint.contour_synth("rbc", n=1)
    with pytest.raises(softjoint.InputError, match=r"^sigma must be finite"):
        softjoint.contour_synth("movie", sigma=float("nan"))
    with pytest.raises(softjoint.InputError, match=r"^every must be 1\.\.=100"):
        softjoint.contour_synth("movie", every=0)
    with pytest.raises(softjoint.InputError, match="case"):
        softjoint.contour_synth("jellyfish")
