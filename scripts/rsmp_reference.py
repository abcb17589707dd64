#!/usr/bin/env python3
"""An independent RSMP (rigid CPD + soft correspondences + PCA) to compare cohortforge with.

Written from the method (SPEC sections 2.2-2.3), with pycpd for rigid CPD and scikit-learn for
PCA. It runs `cohortforge fit` and `cohortforge evaluate` on the same mesh directories, then
its own pipeline with the same template (the training mesh whose vertex count is closest to
the median), the same registration settings (24 axis-permutation starts ranked by surface
fit, outlier weight 0.1, no scale), generalised Procrustes alignment of the normalised shapes
(unless the params say `"procrustes": false`), the same number of PCA modes, Gaussian
sampling and the same distances, and prints both side by side with the wall time of each.

  python3 scripts/rsmp_reference.py --cohortforge target/release/cohortforge \
      --train phantoms/train --test phantoms/test [--params '{...}'] [--samples 100]

Needs numpy, scipy, scikit-learn and pycpd from PyPI. Reads OBJ meshes (as written by
`cohortforge phantoms`).
"""

import argparse
import itertools
import json
import os
import re
import subprocess
import sys
import tempfile
import time

import numpy as np
from pycpd import RigidRegistration
from scipy.spatial import cKDTree
from sklearn.decomposition import PCA

OUTLIER_WEIGHT = 0.1
SEARCH_POINTS, SEARCH_ITERATIONS = 300, 30
FULL_ITERATIONS = 100
ROW_MASS_FLOOR = 1e-12


def read_obj(path):
    vertices, faces = [], []
    with open(path) as f:
        for line in f:
            parts = line.split()
            if not parts:
                continue
            if parts[0] == "v":
                vertices.append([float(c) for c in parts[1:4]])
            elif parts[0] == "f":
                idx = [int(p.split("/")[0]) for p in parts[1:]]
                for k in range(1, len(idx) - 1):
                    faces.append([idx[0] - 1, idx[k] - 1, idx[k + 1] - 1])
    return np.array(vertices), np.array(faces, dtype=np.int64)


def read_dir(directory):
    names = sorted(n for n in os.listdir(directory) if n.endswith(".obj"))
    return names, [read_obj(os.path.join(directory, n)) for n in names]


def volume_ml(vertices, faces):
    a, b, c = (vertices[faces[:, k]] for k in range(3))
    return np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0 / 1000.0


def median_resolution_index(meshes):
    counts = [len(v) for v, _ in meshes]
    median = sorted(counts)[len(counts) // 2]
    return min(range(len(counts)), key=lambda i: (abs(counts[i] - median), i))


def axis_permutation_rotations():
    """The 24 proper rotations that map the coordinate axes onto signed coordinate axes."""
    out = []
    for perm in itertools.permutations(range(3)):
        for signs in itertools.product((1.0, -1.0), repeat=3):
            r = np.zeros((3, 3))
            for row, (col, sign) in enumerate(zip(perm, signs)):
                r[row, col] = sign
            if np.linalg.det(r) > 0:
                out.append(r)
    return out


class FixedScaleRegistration(RigidRegistration):
    """pycpd's rigid CPD with the scale held at 1 (cohortforge's default `scale: false`)."""

    def update_transform(self):
        super().update_transform()
        self.s = 1.0
        mu_x = np.sum(np.dot(self.P, self.X), axis=0) / self.Np
        mu_y = np.sum(np.dot(self.P.T, self.Y), axis=0) / self.Np
        self.t = mu_x - np.dot(self.R.T, mu_y)

    def update_variance(self):
        qprev = self.q
        tr_ar = np.trace(np.dot(self.A, self.R))
        xpx = np.dot(self.Pt1.T, np.sum(self.X_hat * self.X_hat, axis=1))
        residual = xpx - 2 * tr_ar + self.YPY
        self.q = residual / (2 * self.sigma2) + self.D * self.Np / 2 * np.log(self.sigma2)
        self.diff = np.abs(self.q - qprev)
        self.sigma2 = max(residual / (self.Np * self.D), self.tolerance / 10)


def subsample(points, n):
    stride = max(1, -(-len(points) // n))
    return points[::stride]


def surface_fit(moved, data):
    return 0.5 * (cKDTree(data).query(moved)[0].mean() + cKDTree(moved).query(data)[0].mean())


def start(template, data, rotation):
    """The template rotated about its centroid and moved onto the data's centroid."""
    return (template - template.mean(0)) @ rotation.T + data.mean(0)


def register(template, data):
    """Returns a function mapping data points into the template frame, and the posterior."""
    small_data = subsample(data, SEARCH_POINTS)
    best = None
    for rotation in axis_permutation_rotations():
        moved = start(subsample(template, SEARCH_POINTS), small_data, rotation)
        reg = FixedScaleRegistration(
            X=small_data, Y=moved, w=OUTLIER_WEIGHT, max_iterations=SEARCH_ITERATIONS
        )
        ty, _ = reg.register()
        fit = surface_fit(ty, small_data)
        if best is None or fit < best[0]:
            best = (fit, rotation)
    rotation = best[1]
    y0 = start(template, data, rotation)
    reg = FixedScaleRegistration(X=data, Y=y0, w=OUTLIER_WEIGHT, max_iterations=FULL_ITERATIONS)
    reg.register()
    reg.expectation()  # the posterior at the final transform and variance
    s, r, t = reg.get_registration_parameters()
    cy, cx = template.mean(0), data.mean(0)

    def to_template(x):
        in_start = ((x - t) @ r.T) / s  # undo T(y0) = s·y0·R + t
        return (in_start - cx) @ rotation + cy  # undo the start

    return to_template, reg.P


def normalised_shape(template, data, to_template, p):
    p1 = p.sum(axis=1)
    px = p @ data
    h = np.empty_like(template)
    ok = p1 > ROW_MASS_FLOOR
    h[ok] = px[ok] / p1[ok, None]
    if (~ok).any():
        # Rows that claim no data take the data point nearest to the moved template point.
        tree = cKDTree(to_template(data))
        h[~ok] = data[tree.query(template[~ok])[1]]
    return to_template(h)


def kabsch(src, dst):
    """Rotation r and translation t with dst ≈ src @ r.T + t (least squares, proper)."""
    cs, cd = src.mean(0), dst.mean(0)
    u, _, vt = np.linalg.svd((dst - cd).T @ (src - cs))
    d = np.sign(np.linalg.det(u @ vt))
    r = u @ np.diag([1.0, 1.0, d]) @ vt
    return r, cd - cs @ r.T


def generalised_procrustes(shapes, iterations=20):
    """Rigid poses (r, t) aligning each shape [M, 3] onto the mean of the aligned shapes,
    the mean kept in the frame of the plain average."""
    anchor = np.mean(shapes, axis=0)
    mean = anchor
    for _ in range(iterations):
        aligned = [h @ r.T + t for h in shapes for r, t in [kabsch(h, mean)]]
        nxt = np.mean(aligned, axis=0)
        r, t = kabsch(nxt, anchor)
        nxt = nxt @ r.T + t
        moved = np.mean(np.sum((nxt - mean) ** 2, axis=1))
        mean = nxt
        if moved < 1e-18 * np.mean(np.sum((anchor - anchor.mean(0)) ** 2, axis=1)):
            break
    return [kabsch(h, mean) for h in shapes]


def distances(g, h):
    """HD, ED (g to h), ED* (h to g), CD, all vertex to vertex (mm)."""
    ab = cKDTree(h).query(g)[0]
    ba = cKDTree(g).query(h)[0]
    return {"hd": max(ab.max(), ba.max()), "ed": ab.mean(), "ed_star": ba.mean(), "cd": ab.mean() + ba.mean()}


def summary(rows):
    return {k: (float(np.mean([r[k] for r in rows])), float(np.std([r[k] for r in rows], ddof=1)))
            for k in ("hd", "ed", "ed_star", "cd")}


def reference(train, test, n_modes, samples, seed, procrustes):
    template_index = median_resolution_index(train)
    template, template_faces = train[template_index]
    shapes, aligned = [], []
    for vertices, _ in train:
        to_template, p = register(template, vertices)
        shapes.append(normalised_shape(template, vertices, to_template, p))
        aligned.append(to_template(vertices))
    if procrustes:
        poses = generalised_procrustes(shapes)
        shapes = [h @ r.T + t for h, (r, t) in zip(shapes, poses)]
        aligned = [a @ r.T + t for a, (r, t) in zip(aligned, poses)]
    pca = PCA(n_components=n_modes, svd_solver="full").fit(np.array([h.ravel() for h in shapes]))
    mean_shape = pca.mean_.reshape(-1, 3)
    generalisation, matching = [], []
    for vertices, _ in test:
        to_template, p = register(template, vertices)
        h = normalised_shape(template, vertices, to_template, p)
        original = to_template(vertices)
        if procrustes:
            r, t = kabsch(h, mean_shape)
            h, original = h @ r.T + t, original @ r.T + t
        reconstruction = pca.inverse_transform(pca.transform(h.ravel()[None]))[0].reshape(-1, 3)
        generalisation.append(distances(reconstruction, original))
        matching.append(distances(original, h))
    rng = np.random.default_rng(seed)
    codes = rng.standard_normal((samples, n_modes)) * np.sqrt(pca.explained_variance_)
    drawn = pca.inverse_transform(codes).reshape(samples, -1, 3)
    trees = [cKDTree(a) for a in aligned]
    specificity = []
    for sample in drawn:
        k = min(range(len(aligned)), key=lambda k: trees[k].query(sample)[0].mean())
        specificity.append(distances(sample, aligned[k]))
    volumes = [volume_ml(s, template_faces) for s in drawn]
    return {
        "template": template_index,
        "n_modes": n_modes,
        "generalisation": summary(generalisation),
        "matching": summary(matching),
        "specificity": summary(specificity),
        "sample_volume_ml": (float(np.mean(volumes)), float(np.std(volumes, ddof=1))),
    }


def run(cmd):
    started = time.perf_counter()
    done = subprocess.run(cmd, check=True, capture_output=True, text=True)
    return done.stdout, time.perf_counter() - started


def ours(binary, train_dir, test_dir, params, samples, seed, workdir):
    model = os.path.join(workdir, "rsmp.cfmodel")
    out = os.path.join(workdir, "evaluate.json")
    cmd = [binary, "fit", "--train", train_dir, "--model", "rsmp", "--seed", str(seed), "--out", model]
    if params:
        cmd += ["--params", params]
    fit_stdout, fit_s = run(cmd)
    _, eval_s = run([binary, "evaluate", "--model", model, "--test", test_dir,
                     "--samples", str(samples), "--json", out])
    n_modes = int(re.search(r"\((\d+) modes\)", fit_stdout).group(1))
    with open(out) as f:
        report = json.load(f)
    e = report["evaluation"]
    pick = lambda d: {k: (d[k]["mean"], d[k]["std"]) for k in ("hd", "ed", "ed_star", "cd")}
    synthetic = report["cohort"]["biomarkers"]["volume_ml"]
    return {
        "n_modes": n_modes,
        "generalisation": pick(e["generalisation"]),
        "matching": pick(e["matching"]),
        "specificity": pick(e["specificity"]),
        "sample_volume_ml": (synthetic["synthetic"]["mean"], synthetic["synthetic"]["sd"]),
    }, fit_s + eval_s


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--cohortforge", required=True, help="path of the cohortforge binary")
    parser.add_argument("--train", required=True)
    parser.add_argument("--test", required=True)
    parser.add_argument("--params", help="RSMP params (JSON) for cohortforge fit")
    parser.add_argument("--samples", type=int, default=100)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--json", help="file to write both results to")
    args = parser.parse_args()

    with tempfile.TemporaryDirectory() as workdir:
        ours_result, ours_s = ours(args.cohortforge, args.train, args.test, args.params,
                                   args.samples, args.seed, workdir)
    _, train = read_dir(args.train)
    _, test = read_dir(args.test)
    started = time.perf_counter()
    # Generalised Procrustes before the PCA, as cohortforge does unless its params turn it off.
    procrustes = json.loads(args.params or "{}").get("procrustes", True)
    ref = reference(train, test, ours_result["n_modes"], args.samples, args.seed, procrustes)
    ref_s = time.perf_counter() - started
    training_volumes = [volume_ml(v, f) for v, f in train]

    print(f"RSMP on {len(train)} training / {len(test)} test meshes, {ours_result['n_modes']} modes, "
          f"{args.samples} samples (mm, mean ± sd)\n")
    print("| metric | cohortforge | reference (pycpd + scikit-learn) |\n|---|---|---|")
    for part in ("matching", "generalisation", "specificity"):
        for k in ("hd", "ed", "ed_star", "cd"):
            a, b = ours_result[part][k], ref[part][k]
            print(f"| {part} {k.upper().replace('_STAR', '*')} | {a[0]:.2f} ± {a[1]:.2f} | {b[0]:.2f} ± {b[1]:.2f} |")
    a, b = ours_result["sample_volume_ml"], ref["sample_volume_ml"]
    print(f"| sample volume, ml (training {np.mean(training_volumes):.1f} ± {np.std(training_volumes, ddof=1):.1f}) "
          f"| {a[0]:.1f} ± {a[1]:.1f} | {b[0]:.1f} ± {b[1]:.1f} |")
    print(f"| fit + evaluation, s | {ours_s:.1f} | {ref_s:.1f} |")
    print(f"\nreference / cohortforge time: {ref_s / ours_s:.1f}x")
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"cohortforge": ours_result, "cohortforge_seconds": ours_s,
                       "reference": ref, "reference_seconds": ref_s}, f, indent=2)


if __name__ == "__main__":
    sys.exit(main())
