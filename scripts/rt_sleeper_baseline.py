#!/usr/bin/env python3
"""Baseline for the tetmsd haptic-loop benchmark: how late a thread that
does nothing but sleep to absolute 1 ms deadlines wakes on this machine.

Run it the way `softjoint tetmsd pair --rt-priority 10` runs its haptic
thread (SCHED_FIFO 10), for as long as a pair run:

    chrt -f 10 python3 scripts/rt_sleeper_baseline.py 60

Prints the ticks whose wake-up came a whole period (1 ms) or more after the
deadline ("missed", as the haptic loop counts them) and lateness quantiles.
Missed ticks here belong to the machine (kernel preemption model, other
load), not to the tetmsd code.
"""
import sys
import time

seconds = float(sys.argv[1]) if len(sys.argv) > 1 else 10.0
ticks = int(seconds * 1000)
t0 = time.perf_counter()
late_us = []
for k in range(ticks):
    deadline = t0 + k * 0.001
    while True:
        now = time.perf_counter()
        if now >= deadline:
            break
        time.sleep(deadline - now)
    late_us.append((time.perf_counter() - deadline) * 1e6)
s = sorted(late_us)
q = lambda p: s[min(len(s) - 1, int(p * len(s)))]
print(
    f"{ticks} ticks, {sum(1 for v in late_us if v >= 1000.0)} missed; "
    f"lateness p50 {q(0.5):.0f} us, p99 {q(0.99):.0f} us, p99.9 {q(0.999):.0f} us, max {s[-1]:.0f} us"
)
