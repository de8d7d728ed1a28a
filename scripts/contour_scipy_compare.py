#!/usr/bin/env python3
"""Compare softjoint's periodic smoothing spline (Fujioka & Kano, seed 000)
with SciPy/FITPACK's periodic smoothing spline (``splrep(..., per=1)``,
Dierckx's ``percur``) on the same noisy contours.

The data are the paper's red-blood-cell contour, Eq. 38, at fixed s
(one closed contour r(t), t in [0, 10), theta = 2 pi t / 10), sampled at N
equally spaced t with Gaussian noise sigma = 0.3 as in the paper, N = 5 to
40. FITPACK has no periodic *surface* smoother (scipy/scipy#11916), so the
comparison is on these one-dimensional slices; the surface itself is
studied in ``plant-models/tests/contour_paper.rs``.

Methods, all on the same replicates:
  * softjoint, lambda = 1e-3, m = 10 knot intervals, weights 1/N (the paper);
  * softjoint, lambda by GCV, m = 10;
  * FITPACK, smoothing condition s = N sigma^2 (sum of squared residuals,
    the value FITPACK recommends when sigma is known), knots chosen by FITPACK;
  * FITPACK, s = 0 (periodic interpolation), for reference.

Error: RMS over 200 equally spaced t of (fit - truth), mean over replicates.
Not part of the test suite. Usage (after ``cargo build --release -p host-tools``):

    python3 scripts/contour_scipy_compare.py [--softjoint target/release/softjoint]
        [--reps 200] [--seed 1] [--figure out.svg]

Needs numpy, scipy (and matplotlib for --figure): pip install numpy scipy matplotlib
"""
import argparse
import csv
import json
import os
import subprocess
import sys
import tempfile

import numpy as np
from scipy.interpolate import splev, splrep

DOMAIN = 10.0
SIGMA = 0.3
LAMBDA = 1e-3
KNOTS = 10
NS = [5, 10, 20, 40]
EVAL = 200


def f38(s, t):
    """Eq. 38 as printed: sqrt(cos th + sqrt(b^4 - sin^2 th))."""
    b = 1.1 + 0.4 * np.abs(np.sin(1.256 * s))
    th = 36.0 * np.pi / 180.0 * t
    return np.sqrt(np.cos(th) + np.sqrt(b**4 - np.sin(th) ** 2))


def softjoint_fit(binary, data, lam, workdir):
    """Fits every row of `data` (replicates x N) as one frame; returns the
    fitted radius at EVAL angles per replicate, and the lambdas used."""
    reps, n = data.shape
    path = os.path.join(workdir, "data.csv")
    with open(path, "w") as fh:
        fh.write("frame,angle_rad,radius\n")
        for r in range(reps):
            for j in range(n):
                theta = 2.0 * np.pi * j / n
                fh.write(f"{r},{theta:.12f},{data[r, j]:.12f}\n")
    out = os.path.join(workdir, "fit")
    cmd = [binary, "contour", "fit", path, "--model", "signature",
           "--knots", str(KNOTS), "--lambda", lam, "--samples", str(EVAL),
           "--out", out, "--json", "--signed-radii", "--allow-unverified"]
    res = subprocess.run(cmd, capture_output=True, text=True)
    if res.returncode != 0:
        sys.exit(f"softjoint failed: {' '.join(cmd)}\n{res.stderr}")
    summary = json.loads(res.stdout)
    fitted = np.zeros((reps, EVAL))
    with open(os.path.join(out, "fit.csv")) as fh:
        for row in csv.DictReader(fh):
            fitted[int(float(row["frame"])), int(row["k"])] = float(row["radius"])
    lambdas = [f["lambda"] for f in summary["per_frame"]]
    return fitted, lambdas


def fitpack_fit(t, d, s):
    """Periodic smoothing spline of FITPACK through (t, d) on [0, 10)."""
    x = np.append(t, DOMAIN)
    y = np.append(d, d[0])
    tck = splrep(x, y, s=s, per=1)
    return splev(np.linspace(0.0, DOMAIN, EVAL, endpoint=False), tck)


def rms(a, b):
    return float(np.sqrt(np.mean((a - b) ** 2)))


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    root = os.path.dirname(here)
    default_bin = os.path.join(root, "target", "release", "softjoint")
    if not os.path.exists(default_bin):
        default_bin = os.path.join(root, "target", "debug", "softjoint")
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--softjoint", default=default_bin)
    ap.add_argument("--reps", type=int, default=200)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--slices", type=float, nargs="+", default=[0.0, 1.25, 3.3])
    ap.add_argument("--figure", default=None, help="write an SVG chart here")
    a = ap.parse_args()
    rng = np.random.default_rng(a.seed)
    t_eval = np.linspace(0.0, DOMAIN, EVAL, endpoint=False)
    methods = ["softjoint λ=1e-3", "softjoint GCV", "FITPACK s=Nσ²", "FITPACK s=0"]
    results = {}  # (s0, method) -> list over N of (mean rms, sd, noise-free rms)
    with tempfile.TemporaryDirectory() as work:
        for s0 in a.slices:
            truth_eval = f38(s0, t_eval)
            for n in NS:
                t = DOMAIN * np.arange(n) / n
                truth = f38(s0, t)
                noisy = truth + SIGMA * rng.standard_normal((a.reps, n))
                clean = truth[None, :]
                for name, lam in [(methods[0], f"{LAMBDA}"), (methods[1], "gcv")]:
                    fit, lams = softjoint_fit(a.softjoint, noisy, lam, work)
                    fit0, _ = softjoint_fit(a.softjoint, clean, lam, work)
                    errs = [rms(fit[r], truth_eval) for r in range(a.reps)]
                    results.setdefault((s0, name), []).append(
                        (np.mean(errs), np.std(errs), rms(fit0[0], truth_eval),
                         float(np.median(lams))))
                for name, s in [(methods[2], n * SIGMA**2), (methods[3], 0.0)]:
                    errs = []
                    for r in range(a.reps):
                        try:
                            errs.append(rms(fitpack_fit(t, noisy[r], s), truth_eval))
                        except Exception as e:  # FITPACK refuses some inputs
                            errs.append(float("nan"))
                            print(f"FITPACK failed (N={n}, s={s}): {e}", file=sys.stderr)
                    try:
                        e0 = rms(fitpack_fit(t, truth, s), truth_eval)
                    except Exception:
                        e0 = float("nan")
                    results.setdefault((s0, name), []).append(
                        (np.nanmean(errs), np.nanstd(errs), e0, float("nan")))
    print(f"Eq. 38 slices, σ = {SIGMA}, {a.reps} replicates, seed {a.seed}; "
          "RMS error to the true contour (mean ± sd over replicates) "
          "[noise-free fit]")
    for s0 in a.slices:
        print(f"\ns = {s0}:")
        print("| N | " + " | ".join(methods) + " |")
        print("|---|" + "---|" * len(methods))
        for i, n in enumerate(NS):
            cells = []
            for m in methods:
                mean, sd, e0, lam = results[(s0, m)][i]
                extra = f", λ̃ {lam:.1e}" if m == methods[1] else ""
                cells.append(f"{mean:.4f} ± {sd:.4f} [{e0:.4f}{extra}]")
            print(f"| {n} | " + " | ".join(cells) + " |")
    if a.figure:
        import matplotlib
        matplotlib.use("Agg")
        matplotlib.rcParams["svg.fonttype"] = "none"  # text as text: a small file
        import matplotlib.pyplot as plt
        fig, axes = plt.subplots(1, len(a.slices), figsize=(4.2 * len(a.slices), 3.6),
                                 sharey=True)
        for ax, s0 in zip(np.atleast_1d(axes), a.slices):
            for m, style in zip(methods, ["o-", "s--", "^-", "v:"]):
                ax.plot(NS, [r[0] for r in results[(s0, m)]], style, label=m)
            ax.set_xscale("log", base=2)
            ax.set_xticks(NS, [str(n) for n in NS])
            ax.set_yscale("log")
            ax.set_xlabel("N points per contour")
            ax.set_title(f"Eq. 38 contour at s = {s0}")
            ax.grid(True, which="both", alpha=0.3)
        np.atleast_1d(axes)[0].set_ylabel("mean RMS error to the truth")
        np.atleast_1d(axes)[0].legend(fontsize=8)
        fig.tight_layout()
        fig.savefig(a.figure)
        print(f"\nfigure written to {a.figure}")


if __name__ == "__main__":
    main()
