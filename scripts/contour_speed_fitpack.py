#!/usr/bin/env python3
"""Per-frame speed of `softjoint contour fit` against SciPy/FITPACK's
periodic smoothing spline (``splrep(..., per=1)``) on the same contours,
side by side in one run (issue 34).

The data: F frames of one noisy closed contour each, N points as
(angle, radius) at equally spaced angles (an ellipse-like signature with
1 % noise). softjoint fits every frame as a periodic signature with the
knots and lambda given (no GCV search), through the whole command line:
reading the CSV, the fits, the per-frame checks (issue 29: two half-data
fits, the data polygon, curvature and self-intersection sampling) and
writing its files. FITPACK gets the same samples, one ``splrep(per=1)``
per frame with its smoothing condition s given (the data's noise
N sigma^2), in a Python loop; its time does not include reading or
writing anything. The two are run alternately, REPS times each, and the
medians compared.

FITPACK has no "lambda given" mode. With s given it chooses its knots
(adding them until the least-squares residual is below s) and then
searches its smoothing factor p (a root search, several banded solves)
until the residual equals s: more work than our one solve with the knots
and lambda given. Its nearest single-solve case is ``splrep(t=..., per=1)``
with our knots given (``task=-1``): the periodic least-squares spline on
the same knots with no smoothing term, timed too. With ``--example`` the
project's fit alone is timed in-process as well (the example
``contour_fit_speed`` of plant-contour: ``fit_signature`` per frame, and
``fit_contours``, the fit and every per-frame check, without file I/O).

Usage (after ``cargo build --release -p host-tools`` and
``cargo build --release -p plant-contour --example contour_fit_speed``):

    python3 scripts/contour_speed_fitpack.py [--softjoint target/release/softjoint]
        [--example target/release/examples/contour_fit_speed]
        [--frames 200] [--points 64] [--knots 16] [--reps 5] [--marginal 1000]

With ``--marginal F2`` the command is also run on the first F2 frames of
the same kind of data (F2 > frames), alternating with the other runs,
and the time per added frame, (median at F2 − median at frames) /
(F2 − frames), is set beside ``splrep``'s time per frame: the per-frame
cost without the run's fixed cost (process start, thread pool, five
files flushed to disk).

Needs numpy and scipy (pip install numpy scipy).
"""
import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np
from scipy.interpolate import splrep


def contours(frames, points, seed=34):
    rng = np.random.default_rng(seed)
    theta = 2 * np.pi * np.arange(points) / points
    data = []
    for f in range(frames):
        a, b = 40 + 5 * np.sin(f / 10), 30 + 3 * np.cos(f / 7)
        r = a * b / np.sqrt((b * np.cos(theta)) ** 2 + (a * np.sin(theta)) ** 2)
        data.append(r + rng.normal(0, 0.01 * 35, points))
    return theta, data


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    default_bin = os.path.join(here, "..", "target", "release", "softjoint")
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--softjoint", default=default_bin)
    ap.add_argument("--frames", type=int, default=200)
    ap.add_argument("--points", type=int, default=64)
    ap.add_argument("--knots", type=int, default=16)
    ap.add_argument("--lambda", dest="lam", default="1e-3")
    ap.add_argument("--reps", type=int, default=5)
    ap.add_argument("--example", default=None,
                    help="the contour_fit_speed example, to time the fit alone in-process")
    ap.add_argument("--marginal", type=int, default=None, metavar="F2",
                    help="also run the command on F2 frames and report the time per added frame")
    a = ap.parse_args()
    if a.marginal is not None and a.marginal <= a.frames:
        sys.exit(f"--marginal must exceed --frames ({a.frames}), got {a.marginal}")
    theta, data = contours(max(a.frames, a.marginal or 0), a.points)
    sigma = 0.01 * 35
    with tempfile.TemporaryDirectory() as work:
        def write_data(name, frames):
            path = os.path.join(work, name)
            with open(path, "w") as fh:
                fh.write("frame,angle_rad,radius\n")
                for f, r in enumerate(data[:frames]):
                    for t, v in zip(theta, r):
                        fh.write(f"{f},{t:.12f},{v:.12f}\n")
            return path

        def command(path):
            return [a.softjoint, "contour", "fit", path, "--model", "signature",
                    "--knots", str(a.knots), "--lambda", a.lam, "--samples", "64",
                    "--out", os.path.join(work, "out"), "--json", "--allow-unverified"]

        path = write_data("data.csv", a.frames)
        cmd = command(path)
        cmd2 = command(write_data("more.csv", a.marginal)) if a.marginal else None
        data = data[:a.frames]
        ours, theirs, lsq, alone, checked, more = [], [], [], [], [], []
        # Our knots: `knots` equal intervals over [0, 2 pi); FITPACK takes
        # the interior ones.
        t_ours = np.linspace(0, 2 * np.pi, a.knots + 1)[1:-1]
        for _ in range(a.reps):
            t0 = time.perf_counter()
            res = subprocess.run(cmd, capture_output=True, text=True)
            ours.append(time.perf_counter() - t0)
            if res.returncode != 0:
                sys.exit(f"softjoint failed: {res.stderr}")
            if cmd2:
                t0 = time.perf_counter()
                res = subprocess.run(cmd2, capture_output=True, text=True)
                more.append(time.perf_counter() - t0)
                if res.returncode != 0:
                    sys.exit(f"softjoint failed on {a.marginal} frames: {res.stderr}")
            # FITPACK: a closed contour needs the first point repeated at
            # 2 pi for per=1.
            tt = np.append(theta, 2 * np.pi)
            t0 = time.perf_counter()
            for r in data:
                splrep(tt, np.append(r, r[0]), per=1, s=a.points * sigma ** 2)
            theirs.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            for r in data:
                splrep(tt, np.append(r, r[0]), per=1, t=t_ours, task=-1)
            lsq.append(time.perf_counter() - t0)
            if a.example:
                res = subprocess.run([a.example, path, str(a.knots), a.lam, "5", "64"],
                                     capture_output=True, text=True)
                if res.returncode != 0:
                    sys.exit(f"the example failed: {res.stderr}")
                fig = dict(line.split() for line in res.stdout.splitlines())
                alone.append(float(fig["fit_only_ms"]))
                checked.append(float(fig["fit_and_checks_ms"]))
    mo, mt = statistics.median(ours), statistics.median(theirs)
    print(f"{a.frames} frames x {a.points} points, knots {a.knots}, lambda {a.lam}; "
          f"median of {a.reps} alternating runs")
    print(f"softjoint contour fit (whole command, checks included): {1e3 * mo / a.frames:.3f} ms per frame "
          f"({mo:.3f} s)")
    print(f"FITPACK splrep(per=1), s = N sigma^2, fit only: {1e3 * mt / a.frames:.3f} ms per frame "
          f"({mt:.3f} s)")
    ml = statistics.median(lsq)
    print(f"FITPACK splrep(per=1, t = our knots, task=-1), least squares, fit only: "
          f"{1e3 * ml / a.frames:.3f} ms per frame")
    print(f"ratio softjoint whole command / FITPACK s given: {mo / mt:.2f}")
    if more:
        mm = statistics.median(more)
        added = (mm - mo) / (a.marginal - a.frames)
        print(f"softjoint whole command on {a.marginal} frames: {mm:.3f} s; "
              f"per added frame ({a.frames} -> {a.marginal}): {1e3 * added:.4f} ms")
        print(f"ratio softjoint per added frame / FITPACK s given per frame: "
              f"{added / (mt / a.frames):.2f}")
    if a.example:
        fa, fc = statistics.median(alone), statistics.median(checked)
        print(f"softjoint fit alone (fit_signature, lambda given, in-process): {fa:.3f} ms per frame")
        print(f"softjoint fit and every per-frame check, no file I/O (fit_contours): {fc:.3f} ms per frame")
        print(f"ratio softjoint fit alone / FITPACK s given: {fa / (1e3 * mt / a.frames):.2f}; "
              f"/ FITPACK least squares on our knots: {fa / (1e3 * ml / a.frames):.2f}")


if __name__ == "__main__":
    main()
