#!/usr/bin/env python3
"""Joint A^mu that density models of the biomarkers themselves reach.

Reads the meshes (OBJ) of a `cohortforge phantoms` directory, measures volume (ml), area
(cm^2), sphericity and the three principal extents (mm, along the area-weighted principal axes
of the surface), takes the first --train meshes as the training population and the rest as
fresh subjects, and prints the joint acceptance inside all six mu +- 2 sd intervals of:
the fresh subjects, the training meshes themselves, and draws from Gaussian mixtures fitted
to the training biomarkers (number of components and covariance type scored by 5-fold
held-out log-likelihood). A shape model can only do worse than a density fitted to the
biomarkers directly, so these rates bound what a generator of that family can score.

With --repeats R it also splits the first R * --train meshes into R disjoint training sets and
scores, against each set's intervals, every mesh outside it (the population's own rate: what
a generator that draws exactly from the population is expected to score) and draws from the
Gaussian with that set's biomarker mean and covariance; then the mean and sd over the sets.

    cohortforge phantoms --family lv --count 300 --seed 1 --out lv300
    python scripts/acceptance_ceiling.py lv300 --train 100
    cohortforge phantoms --family liver --count 1000 --seed 7 --out liver1000
    python scripts/acceptance_ceiling.py liver1000 --train 100 --repeats 10

Needs numpy and scikit-learn.
"""

import argparse
import glob
import os

import numpy as np
from sklearn.mixture import GaussianMixture
from sklearn.model_selection import KFold


def load_obj(path):
    vertices, faces = [], []
    with open(path) as f:
        for line in f:
            if line.startswith("v "):
                vertices.append([float(x) for x in line.split()[1:4]])
            elif line.startswith("f "):
                faces.append([int(x.split("/")[0]) - 1 for x in line.split()[1:4]])
    return np.array(vertices), np.array(faces)


def biomarkers(vertices, faces):
    a, b, c = (vertices[faces[:, k]] for k in range(3))
    areas = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
    volume = np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0
    area = areas.sum()
    centroid = (areas[:, None] * (a + b + c) / 3.0).sum(0) / area
    covariance = np.zeros((3, 3))
    for corner in (a, b, c):
        d = corner - centroid
        covariance += np.einsum("i,ij,ik->jk", areas, d, d)
    _, axes = np.linalg.eigh(covariance)
    projected = (vertices - centroid) @ axes[:, ::-1]
    extents = projected.max(0) - projected.min(0)
    sphericity = np.pi ** (1 / 3) * (6 * abs(volume)) ** (2 / 3) / area
    return [volume / 1000.0, area / 100.0, sphericity, *extents]


def joint_rate(mean, sd):
    """Joint A^mu, %, of a [n, 6] sample against the intervals mean +- 2 sd."""
    low, high = mean - 2 * sd, mean + 2 * sd
    return lambda sample: 100.0 * ((sample >= low) & (sample <= high)).all(1).mean()


def repeated(values, args):
    """The population's own rate and the Gaussian yardstick over disjoint training sets."""
    if args.repeats * args.train >= len(values):
        raise SystemExit(
            f"--repeats {args.repeats} x --train {args.train} needs more meshes"
        )
    rng = np.random.default_rng(args.seed)
    print(
        f"{args.repeats} disjoint training sets of {args.train} of {len(values)} meshes"
    )
    print("set  population's own  training meshes  Gaussian yardstick")
    rates = []
    for r in range(args.repeats):
        inside = np.zeros(len(values), dtype=bool)
        inside[r * args.train : (r + 1) * args.train] = True
        train, rest = values[inside], values[~inside]
        mean, sd = train.mean(0), train.std(0, ddof=1)
        joint = joint_rate(mean, sd)
        gaussian = rng.multivariate_normal(
            mean, np.cov(train, rowvar=False), args.draws
        )
        rates.append((joint(rest), joint(train), joint(gaussian)))
        print(
            f"{r:>3}  {rates[-1][0]:>16.1f}  {rates[-1][1]:>15.1f}  {rates[-1][2]:>18.1f}"
        )
    rates = np.array(rates)
    mean, sd = rates.mean(0), rates.std(0, ddof=1)
    print("mean ± sd  " + "  ".join(f"{m:.1f} ± {s:.1f}" for m, s in zip(mean, sd)))
    print()


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("meshes")
    parser.add_argument("--train", type=int, default=100)
    parser.add_argument("--draws", type=int, default=100_000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--repeats", type=int, default=0)
    args = parser.parse_args()
    paths = sorted(glob.glob(os.path.join(args.meshes, "*.obj")))
    values = np.array([biomarkers(*load_obj(p)) for p in paths])
    if args.repeats:
        repeated(values, args)
    train, fresh = values[: args.train], values[args.train :]
    mean, sd = train.mean(0), train.std(0, ddof=1)
    joint = joint_rate(mean, sd)

    print(f"{len(train)} training, {len(fresh)} fresh meshes; joint A^mu, %")
    print(f"fresh subjects: {joint(fresh):.1f}")
    print(f"training meshes against their own intervals: {joint(train):.1f}")
    standard = (train - mean) / sd
    folds = KFold(5, shuffle=True, random_state=args.seed)
    print("components  covariance  held-out log-likelihood  joint A^mu")
    for components in (1, 2, 3, 4, 6):
        for kind in ("full", "tied", "diag"):

            def mixture(x, components=components, kind=kind):
                return GaussianMixture(
                    components,
                    covariance_type=kind,
                    random_state=args.seed,
                    reg_covar=1e-3,
                ).fit(x)

            held_out = np.mean(
                [
                    mixture(standard[t]).score(standard[v])
                    for t, v in folds.split(standard)
                ]
            )
            drawn = mixture(standard).sample(args.draws)[0] * sd + mean
            print(
                f"{components:>10}  {kind:>10}  {held_out:>23.3f}  {joint(drawn):>10.1f}"
            )


if __name__ == "__main__":
    main()
