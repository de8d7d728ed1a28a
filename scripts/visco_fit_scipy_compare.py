#!/usr/bin/env python3
"""Per-trial speed of `softjoint viscoelastic fit` against a SciPy fit of
the same 3-element model (``scipy.signal.lfilter`` for the model,
``scipy.optimize.minimize(method="Nelder-Mead")`` for the fit), side by
side in one run (issue 34).

What is compared, exactly:

* softjoint: one `softjoint viscoelastic fit TRIAL --json` process per
  trial file, timed from launch to exit: reading and checking the CSV, the
  seed-weighted Nelder-Mead fit (a run and one restart), the Gauss-Newton
  uncertainty and the JSON output.
* SciPy: in this Python process (no interpreter start-up counted), for
  each trial ``np.loadtxt`` of the same file and the same fit: the same
  model, cost, weighting, scaling, starting point and initial simplex
  (ln 2 along each ln-parameter), ``xatol`` 1e-4 as ours, and one restart
  from the best point, as ours. The model is ours written as a filter:
  over a step h with the displacement linear between samples, the dashpot
  displacement obeys x[k] = E x[k-1] + g (1 - phi) u[k] + g (phi - E) u[k-1]
  (E = exp(-a h), phi = (1 - E)/(a h), a = (k1 + k2)/b, g = k2/(k1 + k2)),
  which is ``lfilter([b0, b1], [1, -E], ...)``; the force is k2 (u - x).
  The trials must be uniformly sampled (checked, to 1e-9 relative).
  SciPy's Nelder-Mead has no relative cost tolerance; ``fatol`` is set to
  1e-7 times the starting cost's order (the residual scale), which is
  looser or equal to ours, so SciPy is not made to do more work than we do.
  Its time does not include the uncertainty, which ours does.

The two are run alternately, ROUNDS times over all the trials, and the
medians per trial printed with their ratio, and the largest relative
difference between the two fits' parameters.

Trial files: the simulated probe campaign that `softjoint viscoelastic
object --trials-dir DIR` writes (this script writes it if DIR has no
trial_*.csv).

Usage (after ``cargo build --release -p host-tools``):

    python3 scripts/visco_fit_scipy_compare.py [--softjoint target/release/softjoint]
        [--trials-dir DIR] [--count 20] [--rounds 5]

Needs numpy and scipy. Exit 1 when a fit fails, 2 for a bad argument.
"""
import argparse
import glob
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np
from scipy.optimize import minimize
from scipy.signal import lfilter

# The seed's weighting (seed 002 section 4.1), as in
# plant-models/viscoelastic/src/identify/fit.rs.
TAIL_WEIGHT, PEAK_WEIGHT = 100.0, 1000.0


def weights(force):
    peak = int(np.argmax(force))
    w = np.ones_like(force)
    w[peak + 1:] = TAIL_WEIGHT
    w[max(peak - 1, 0):peak + 2] = PEAK_WEIGHT
    return w


def model_force(k1, k2, b, h, u):
    a_h = (k1 + k2) / b * h
    one_minus_e = -np.expm1(-a_h)
    e, phi = 1.0 - one_minus_e, one_minus_e / a_h
    g = k2 / (k1 + k2)
    b0, b1 = g * (1.0 - phi), g * (phi - e)
    # x[0] = 0 (the first sample is the instantaneous response); the
    # filter state carries b1 u[0] into the first step.
    x = np.empty_like(u)
    x[0] = 0.0
    x[1:] = lfilter([b0, b1], [1.0, -e], u[1:], zi=[b1 * u[0]])[0]
    return k2 * (u - x)


def scipy_fit(path):
    data = np.loadtxt(path, delimiter=",", skiprows=1)
    t, u, f = data[:, 0], data[:, 1], data[:, 2]
    dt = np.diff(t)
    h = float(dt.mean())
    if np.max(np.abs(dt - h)) > 1e-9 * h:
        sys.exit(f"{path}: not uniformly sampled; the filter form needs one step")
    n = len(t)
    peak = int(np.argmax(f))
    k_relaxed = f[-1] / u[-1]
    k2_0 = max(1.5 * f[peak] / u[peak], 2.0 * k_relaxed)
    k1_0 = k_relaxed * k2_0 / (k2_0 - k_relaxed)
    b_0 = 0.1 * (t[-1] - t[0]) * (k1_0 + k2_0)
    w = weights(f)
    norm = w.sum()
    scale = 2.0 ** -round(np.log2(np.max(np.abs(f))))

    def cost(x):
        k1, k2, b = np.exp(x)
        r = (model_force(k1, k2, b, h, u) - f) * scale
        c = float(np.dot(w, r * r)) / norm
        return c if np.isfinite(c) else np.inf

    x = np.log([k1_0, k2_0, b_0])
    evaluations = 0
    for _ in range(2):  # a run and one restart, as ours
        simplex = np.vstack([x, x + np.diag(np.full(3, np.log(2.0)))])
        res = minimize(cost, x, method="Nelder-Mead",
                       options=dict(initial_simplex=simplex, xatol=1e-4,
                                    fatol=1e-7 * cost(x), maxfev=2000))
        evaluations += res.nfev
        x = res.x
    return np.exp(x), evaluations, n


def ours_fit(exe, path):
    res = subprocess.run([exe, "viscoelastic", "fit", path, "--json"],
                         capture_output=True, text=True)
    if res.returncode != 0:
        sys.exit(f"softjoint failed on {path}: {res.stderr.strip()}")
    j = json.loads(res.stdout)
    return np.array([j["k1_n_per_m"], j["k2_n_per_m"], j["b_n_s_per_m"]]), j["evaluations"]


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--softjoint", default=os.path.join(here, "..", "target", "release", "softjoint"))
    ap.add_argument("--trials-dir", default=None)
    ap.add_argument("--count", type=int, default=20)
    ap.add_argument("--rounds", type=int, default=5)
    a = ap.parse_args()
    if a.count < 1 or a.rounds < 1:
        print("--count and --rounds must be at least 1", file=sys.stderr)
        sys.exit(2)
    with tempfile.TemporaryDirectory() as work:
        d = a.trials_dir or os.path.join(work, "trials")
        if not glob.glob(os.path.join(d, "trial_*.csv")):
            subprocess.run([a.softjoint, "viscoelastic", "object", "--trials-dir", d,
                            "--out-dir", os.path.join(work, "out")],
                           check=True, capture_output=True)
        paths = sorted(glob.glob(os.path.join(d, "trial_*.csv")))[:a.count]
        ours_t, theirs_t = [], []
        worst, ev_o, ev_s, samples = 0.0, [], [], []
        for _ in range(a.rounds):
            t0 = time.perf_counter()
            po = [ours_fit(a.softjoint, p) for p in paths]
            ours_t.append((time.perf_counter() - t0) / len(paths))
            t0 = time.perf_counter()
            ps = [scipy_fit(p) for p in paths]
            theirs_t.append((time.perf_counter() - t0) / len(paths))
        for (xo, eo), (xs, es, n) in zip(po, ps):
            worst = max(worst, float(np.max(np.abs(xs / xo - 1.0))))
            ev_o.append(eo)
            ev_s.append(es)
            samples.append(n)
    mo, ms = statistics.median(ours_t), statistics.median(theirs_t)
    print(f"{len(paths)} trials ({min(samples)}-{max(samples)} samples), median of "
          f"{a.rounds} alternating rounds; load {os.getloadavg()[0]:.2f}")
    print(f"softjoint viscoelastic fit (process per trial, read + fit + uncertainty): "
          f"{1e3 * mo:.2f} ms per trial; {statistics.mean(ev_o):.0f} evaluations")
    print(f"SciPy lfilter + Nelder-Mead (loadtxt + fit, in-process): "
          f"{1e3 * ms:.2f} ms per trial; {statistics.mean(ev_s):.0f} evaluations")
    print(f"ratio softjoint / SciPy: {mo / ms:.3f}")
    print(f"largest relative difference of k1, k2, b between the fits: {worst:.2e}")


if __name__ == "__main__":
    main()
