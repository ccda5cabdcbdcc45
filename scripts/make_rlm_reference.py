#!/usr/bin/env python3
"""Reference values for rangex's robust fit from statsmodels (Debian's python3-statsmodels).

Writes tests/data/rlm/<name>.csv (columns T,lnI) and tests/data/rlm/reference.csv with the
parameters statsmodels' RLM(lnI ~ 1 + T, M=TukeyBiweight(c)).fit() returns for each data
set and tuning constant, and tests/data/rlm/reference_quadratic.csv with those of
RLM(lnI ~ 1 + T + T^2) for the data sets a parabola is for. Run from the repository root:  python3 scripts/make_rlm_reference.py
"""
import csv
import os

import numpy as np
import statsmodels
import statsmodels.api as sm

OUT = os.path.join("tests", "data", "rlm")


def clean(rng):
    t = rng.uniform(2, 45, 500)
    return t, 8.2 - 0.031 * t + rng.normal(0, 0.01, t.size)


def outliers20(rng):
    # 20 % outliers: bone fragments below the line, air pockets above it.
    t = rng.uniform(3, 40, 800)
    y = 8.1 - 0.029 * t + rng.normal(0, 0.012, t.size)
    bad = rng.choice(t.size, 160, replace=False)
    y[bad[:120]] -= rng.uniform(0.05, 0.4, 120)
    y[bad[120:]] += rng.uniform(0.05, 0.2, 40)
    return t, y


def funnel(rng):
    # X-ray noise follows the signal: the log-domain spread shrinks where the meat is thin.
    t = rng.uniform(1, 45, 1000)
    intensity = 3600 * np.exp(-0.03 * t)
    counts = rng.normal(intensity * 10, np.sqrt(intensity * 10)) / 10 + rng.normal(0, 2, t.size)
    return t, np.log(counts)


def small(rng):
    t = np.array([2.0, 5.5, 9.1, 12.0, 15.2, 19.9, 23.3, 27.0, 31.4, 35.0, 39.8, 44.1])
    y = 8.0 - 0.03 * t + rng.normal(0, 0.01, t.size)
    y[3] -= 0.3
    y[8] += 0.25
    return t, y


def hardened(rng):
    # A polychromatic beam: the effective attenuation falls with the path (beam hardening),
    # with bone fragments below the curve and air pockets above it.
    t = rng.uniform(1, 40, 1200)
    att = 0.03 * t
    y = 8.2 - att / (1 + 0.3 * att) + rng.normal(0, 0.01, t.size)
    bad = rng.choice(t.size, 150, replace=False)
    y[bad[:110]] -= rng.uniform(0.05, 0.3, 110)
    y[bad[110:]] += rng.uniform(0.05, 0.15, 40)
    return t, y


def write_points(name, t, y):
    with open(os.path.join(OUT, name + ".csv"), "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["T", "lnI"])
        for a, b in zip(t, y):
            w.writerow([repr(float(a)), repr(float(b))])


def quadratic_rows():
    rows = []
    for seed, make in [(1004, hardened), (1001, outliers20), (1002, funnel)]:
        rng = np.random.RandomState(seed)
        t, y = make(rng)
        if make is hardened:
            write_points(make.__name__, t, y)
        design = np.column_stack([np.ones_like(t), t, t * t])
        for c in (5.0, 4.685):
            res = sm.RLM(y, design, M=sm.robust.norms.TukeyBiweight(c=c)).fit()
            rows.append([make.__name__, repr(c)] + [repr(float(v)) for v in res.params] +
                        [repr(float(res.scale)), res.fit_history["iteration"]])
    with open(os.path.join(OUT, "reference_quadratic.csv"), "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["dataset", "c", "beta0", "beta1", "beta2", "scale", "iterations"])
        w.writerows(rows)


def main():
    os.makedirs(OUT, exist_ok=True)
    rows = []
    for seed, make in enumerate([clean, outliers20, funnel, small]):
        rng = np.random.RandomState(1000 + seed)
        t, y = make(rng)
        name = make.__name__
        with open(os.path.join(OUT, name + ".csv"), "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(["T", "lnI"])
            for a, b in zip(t, y):
                w.writerow([repr(float(a)), repr(float(b))])
        for c in (5.0, 4.685):
            res = sm.RLM(y, sm.add_constant(t), M=sm.robust.norms.TukeyBiweight(c=c)).fit()
            rows.append([name, repr(c), repr(float(res.params[0])), repr(float(res.params[1])),
                         repr(float(res.scale)), res.fit_history["iteration"]])
    with open(os.path.join(OUT, "reference.csv"), "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["dataset", "c", "beta0", "beta1", "scale", "iterations"])
        w.writerows(rows)
    quadratic_rows()
    print("statsmodels", statsmodels.__version__, "->", OUT)


if __name__ == "__main__":
    main()
