#!/usr/bin/env python3
"""Joint A^mu of RSMP cohorts drawn from the same PCA in different ways.

An RSMP model draws each PCA coefficient from an independent Gaussian. Its cohorts keep each
biomarker's spread, but on LV phantoms they stay inside all six mu +- 2 sd intervals of the
training meshes less often (84-86%) than fresh subjects of the population do. This script
asks whether another way of drawing the coefficients, still from the model's own training
shapes and modes, does better without narrowing the cohort or copying patients:

- `gaussian`: the service's way, every kept mode independent.
- `ica`: the leading K coefficients from independent components (FastICA), each source from
  its own smoothed distribution, the rest Gaussian (or left out).
- `quadratic`: the leading K coefficients Gaussian, the others their ridge regression on the
  leading ones and their products (a curved mode space) plus a Gaussian residual.
- `local`: the leading K coefficients Gaussian, the others a random Gaussian combination of
  those of the 10 training shapes nearest in the leading coefficients (their spread depends
  on where the leading ones fall).
- `blend`: sums of the deviations of K distinct training shapes, divided by sqrt(K) so that
  the covariance stays the training shapes' (bounded, lighter tails than a Gaussian).
- `smoothed`: a training shape's coefficients plus Gaussian noise of h times their
  covariance, shrunk by 1 / sqrt(1 + h^2) to keep the covariance (a kernel density).
- `selected`: Gaussian draws kept with probability proportional to the ratio of a kernel
  density of the training biomarkers to one of the draws' biomarkers (virtual-population
  selection); it prints the share kept.

It reads a model file written by `cohortforge fit --model rsmp` (its normalised training
shapes, template and PCA), measures the six biomarkers of `acceptance_ceiling.py` on the
first --train meshes of the directory (the training meshes, whose mu +- 2 sd intervals judge
every draw) and on the rest (fresh subjects), and prints for each way of drawing: joint
A^mu, the sd ratio of volume and area and the mean ratio of the major extent against the
training meshes, and the share of draws closer to a training shape (mean vertex distance)
than the 5th percentile of the training shapes' own nearest-neighbour distances. Drawn shapes
are not smoothed as the service smooths them, so rates differ from `cohortforge fit`'s by
about a point; with 1,000 draws a rate's sampling sd is about 1.1 points.

    cohortforge phantoms --family lv --count 400 --seed 1 --out lv400
    mkdir train && cp lv400/lv_0[0-9][0-9].obj train/
    cohortforge fit --train train --model rsmp --seed 1 --out rsmp.cfm
    python scripts/rsmp_samplers.py rsmp.cfm lv400 --train 100

Needs numpy, scipy, scikit-learn and msgpack.
"""

import argparse
import glob
import os

import msgpack
import numpy as np
from acceptance_ceiling import biomarkers, joint_rate, load_obj
from scipy.stats import gaussian_kde
from sklearn.decomposition import FastICA

NEIGHBOURS = 10
RIDGE = 10.0


def load_rsmp(path):
    """(template faces, normalisation centre, scale, PCA mean/modes/variances, shapes mm)."""
    with open(path, "rb") as f:
        data = f.read()
    outer = msgpack.unpackb(data[8:], raw=False, strict_map_key=False)
    if outer["model_type"] != "rsmp":
        raise SystemExit(f"{path} holds a {outer['model_type']} model, not rsmp")
    stored = msgpack.unpackb(outer["model_bytes"][9:], raw=False, strict_map_key=False)
    model = msgpack.unpackb(stored["model"], raw=False, strict_map_key=False)
    pca, norm = model["pca"], model["normalisation"]
    return (
        np.array(model["template"]["faces"]),
        np.array(norm["centre"]),
        norm["scale_mm"],
        np.array(pca["mean"]),
        np.array(pca["modes"]),
        np.array(pca["variances"]),
        np.array(stored["training"]["normalised"][0]),
    )


def smoothed_marginals(sources, n, h, rng):
    """n draws of each column from its own values plus h sd of noise, variance kept."""
    picked = sources[
        rng.integers(0, len(sources), (n, sources.shape[1])),
        np.arange(sources.shape[1]),
    ]
    centre = sources.mean(0)
    noisy = picked + h * sources.std(0) * rng.standard_normal(picked.shape)
    return centre + (noisy - centre) / np.sqrt(1 + h * h)


def quadratic_features(leading):
    """The leading whitened coefficients and their pairwise products, [n, k + k(k+1)/2]."""
    i, j = np.triu_indices(leading.shape[1])
    return np.hstack([leading, leading[:, i] * leading[:, j]])


def ica(white, k, n, rng, trailing=True):
    model = FastICA(k, whiten="unit-variance", random_state=0, max_iter=5000, tol=1e-3)
    sources = model.fit_transform(white[:, :k])
    leading = model.inverse_transform(smoothed_marginals(sources, n, 0.4, rng))
    rest = rng.standard_normal((n, white.shape[1] - k))
    return np.hstack([leading, rest if trailing else 0 * rest])


def quadratic(white, k, n, rng):
    features = quadratic_features(white[:, :k])
    centre = features.mean(0)
    x = features - centre
    rest = white[:, k:]
    weights = np.linalg.solve(x.T @ x + RIDGE * np.eye(x.shape[1]), x.T @ rest)
    residual = np.cov((rest - x @ weights).T)
    leading = rng.standard_normal((n, k))
    noise = rng.multivariate_normal(np.zeros(len(residual)), residual, n)
    return np.hstack(
        [leading, (quadratic_features(leading) - centre) @ weights + noise]
    )


def local(white, k, n, rng):
    leading = rng.standard_normal((n, k))
    rest = white[:, k:]
    drawn = np.empty((n, rest.shape[1]))
    for row, point in enumerate(leading):
        nearest = np.argsort(((white[:, :k] - point) ** 2).sum(1))[:NEIGHBOURS]
        near = rest[nearest]
        centre = near.mean(0)
        weights = rng.standard_normal(NEIGHBOURS) / np.sqrt(NEIGHBOURS - 1)
        drawn[row] = centre + weights @ (near - centre)
    return np.hstack([leading, drawn])


def blend(white, k, n, rng):
    chosen = np.array([rng.choice(len(white), k, replace=False) for _ in range(n)])
    return white[chosen].sum(1) / np.sqrt(k)


def smoothed(white, h, n, rng):
    picked = white[rng.integers(0, len(white), n)]
    return (picked + h * rng.standard_normal(picked.shape)) / np.sqrt(1 + h * h)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("model")
    parser.add_argument("meshes")
    parser.add_argument("--train", type=int, default=100)
    parser.add_argument("--draws", type=int, default=1000)
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    faces, centre, scale, mean, modes, variances, shapes = load_rsmp(args.model)
    paths = sorted(glob.glob(os.path.join(args.meshes, "*.obj")))
    values = np.array([biomarkers(*load_obj(p)) for p in paths])
    train, fresh = values[: args.train], values[args.train :]
    train_mean, sd = train.mean(0), train.std(0, ddof=1)
    joint = joint_rate(train_mean, sd)
    coefficients = ((shapes - centre) / scale).reshape(len(shapes), -1) - mean
    white = (coefficients @ modes.T) / np.sqrt(variances)
    distances = np.sqrt(((shapes[:, None] - shapes[None]) ** 2).sum(-1)).mean(-1)
    np.fill_diagonal(distances, np.inf)
    threshold = np.percentile(distances.min(1), 5)
    rng = np.random.default_rng(args.seed)
    n, kept = args.draws, len(variances)

    def measure(drawn_white):
        drawn_mm = (mean + (drawn_white * np.sqrt(variances)) @ modes).reshape(
            len(drawn_white), -1, 3
        ) * scale + centre
        measured = np.array([biomarkers(x, faces) for x in drawn_mm])
        nearest = np.array(
            [np.sqrt(((shapes - x) ** 2).sum(-1)).mean(-1).min() for x in drawn_mm]
        )
        return measured, nearest

    def report(name, measured, nearest):
        ratio = measured.std(0, ddof=1) / sd
        print(
            f"{name:<34} {joint(measured):>6.1f} {ratio[0]:>9.3f} {ratio[1]:>7.3f}"
            f" {measured[:, 3].mean() / train_mean[3]:>11.3f}"
            f" {100 * (nearest < threshold).mean():>7.1f}"
        )

    print(f"fresh subjects {joint(fresh):.1f}%, training meshes {joint(train):.1f}%;")
    print(f"{kept} modes, near-copy threshold {threshold:.2f} mm, {n} draws each")
    print(
        f"{'drawing':<34} {'A^mu %':>6} {'volume sd':>9} {'area sd':>7}"
        f" {'major mean':>11} {'near %':>7}"
    )
    gaussian = measure(rng.standard_normal((n, kept)))
    report("gaussian", *gaussian)
    for k in (5, 10):
        report(f"ica, K {k}", *measure(ica(white, k, n, rng)))
        report(f"ica, K {k}, no other modes", *measure(ica(white, k, n, rng, False)))
    for k in (3, 5):
        report(f"quadratic, K {k}", *measure(quadratic(white, k, n, rng)))
        report(f"local, K {k}", *measure(local(white, k, n, rng)))
    for k in (2, 4):
        report(f"blend, K {k}", *measure(blend(white, k, n, rng)))
    for h in (0.5, 1.0):
        report(f"smoothed, h {h}", *measure(smoothed(white, h, n, rng)))

    def standard(v):
        return ((v - train_mean) / sd).T

    drawn = standard(gaussian[0])
    ratio = gaussian_kde(standard(train))(drawn) / gaussian_kde(drawn)(drawn)
    keep = rng.random(n) < np.minimum(1.0, ratio / np.quantile(ratio, 0.9))
    report(
        f"selected ({100 * keep.mean():.0f}% kept)",
        gaussian[0][keep],
        gaussian[1][keep],
    )


if __name__ == "__main__":
    main()
