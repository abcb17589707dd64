#!/usr/bin/env python3
"""Joint A^mu of RSMP draws whose leading coefficients come from independent components.

An RSMP model draws each PCA coefficient from a Gaussian, so its biomarkers have Gaussian
tails; the phantoms' parameters are uniform between bounds, with lighter tails. This script
asks whether drawing the leading coefficients from independent components (FastICA) with
each source's own distribution brings the cohort's joint A^mu closer to the population's.

It reads a model file written by `cohortforge fit --model rsmp` (its normalised training
shapes, template and PCA), measures the six biomarkers of `acceptance_ceiling.py` on the
first --train meshes of the directory (the training meshes, whose mu +- 2 sd intervals judge
every draw) and on the rest (fresh subjects), and prints for each way of drawing: joint
A^mu, the sd ratio of volume and area against the training meshes, and the share of draws
closer to a training shape (mean vertex distance) than the 5th percentile of the training
shapes' own nearest-neighbour distances. Drawn shapes are not smoothed as the service
smooths them, so rates differ from `cohortforge fit`'s by about a point.

    cohortforge phantoms --family lv --count 400 --seed 1 --out lv400
    mkdir train && cp lv400/lv_0[0-9][0-9].obj train/
    cohortforge fit --train train --model rsmp --seed 1 --out rsmp.cfm
    python scripts/ica_sampling.py rsmp.cfm lv400 --train 100

Needs numpy, scikit-learn and msgpack.
"""

import argparse
import glob
import os

import msgpack
import numpy as np
from acceptance_ceiling import biomarkers, joint_rate, load_obj
from sklearn.decomposition import FastICA


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


def kurtosis(x):
    """Excess kurtosis per column."""
    z = (x - x.mean(0)) / x.std(0)
    return (z**4).mean(0) - 3.0


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
    sd = train.std(0, ddof=1)
    joint = joint_rate(train.mean(0), sd)
    coefficients = ((shapes - centre) / scale).reshape(len(shapes), -1) - mean
    coefficients = coefficients @ modes.T
    distances = np.sqrt(((shapes[:, None] - shapes[None]) ** 2).sum(-1)).mean(-1)
    np.fill_diagonal(distances, np.inf)
    threshold = np.percentile(distances.min(1), 5)
    rng = np.random.default_rng(args.seed)
    n, kept = args.draws, len(variances)

    def report(name, drawn):
        drawn_mm = (mean + drawn @ modes).reshape(n, -1, 3) * scale + centre
        measured = np.array([biomarkers(x, faces) for x in drawn_mm])
        nearest = np.array(
            [np.sqrt(((shapes - x) ** 2).sum(-1)).mean(-1).min() for x in drawn_mm]
        )
        ratio = measured.std(0, ddof=1) / sd
        print(
            f"{name:<40} {joint(measured):>6.1f} {ratio[0]:>9.2f} {ratio[1]:>7.2f}"
            f" {100 * (nearest < threshold).mean():>7.1f}"
        )

    print(f"fresh subjects {joint(fresh):.1f}%, training meshes {joint(train):.1f}%;")
    print(f"{kept} modes, near-copy threshold {threshold:.2f} mm")
    print(
        f"{'drawing':<40} {'A^mu %':>6} {'volume sd':>9} {'area sd':>7} {'near %':>7}"
    )
    report("Gaussian, every mode", rng.standard_normal((n, kept)) * np.sqrt(variances))
    for k in (5, 7, 10, 15):
        ica = FastICA(
            k, whiten="unit-variance", random_state=0, max_iter=5000, tol=1e-3
        )
        sources = ica.fit_transform(coefficients[:, :k])
        flat = kurtosis(sources) < -0.6
        rest = rng.standard_normal((n, kept - k)) * np.sqrt(variances[k:])
        for h in (0.2, 0.4):
            picked = sources[rng.integers(0, len(sources), (n, k)), np.arange(k)]
            smoothed = (picked + h * rng.standard_normal(picked.shape)) / np.sqrt(
                1 + h * h
            )
            leading = ica.inverse_transform(smoothed)
            report(
                f"ICA {k}, own marginals (h {h}) + Gaussian", np.hstack([leading, rest])
            )
        uniform = rng.uniform(-np.sqrt(3), np.sqrt(3), (n, k)) * sources.std(0)
        gaussian = rng.standard_normal((n, k)) * sources.std(0)
        chosen = np.where(flat, uniform, gaussian) + sources.mean(0)
        leading = ica.inverse_transform(chosen)
        report(f"ICA {k}, uniform where flat + Gaussian", np.hstack([leading, rest]))
        report(
            f"ICA {k}, uniform where flat, no others", np.hstack([leading, 0 * rest])
        )


if __name__ == "__main__":
    main()
