"""How well can any fit of a frame's corners place a block? A check of tagpose.block's figures.

    /usr/bin/python3 bench/block_bound.py DATASET_DIR

DATASET_DIR is a block data set (bench/dev/blocks, or one written by
bench/make_blocks.lua): camera.lua, corners.csv, truth.csv, truth_tags.csv. For every block it
fits the block pose to the corners of its own tags by Gauss-Newton, told each tag's true face
(from truth_tags.csv) and started at the true pose -- the least-squares estimate with nothing
left to guess -- and prints the median centre error for blocks seen with one face and with two
or more, beside the median of the linearised (Cramer-Rao) bound for Gaussian corner noise of
the data set's sigma (default 0.3 px). Needs numpy only (Debian: python3-numpy), not tagpose.
"""

import csv
import re
import sys

import numpy as np


def read_camera(path):
    text = open(path).read()

    def number(key):
        return float(re.search(r"\b%s\s*=\s*([-0-9.eE+]+)" % key, text).group(1))

    return number("fx"), number("fy"), number("cx"), number("cy"), number("tag_size")


def quat_to_matrix(w, x, y, z):
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def rotation_vector(w):
    th = np.linalg.norm(w)
    if th == 0:
        return np.eye(3)
    k = w / th
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(th) * K + (1 - np.cos(th)) * K @ K


def main():
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    d = sys.argv[1]
    sigma = float(sys.argv[2]) if len(sys.argv) > 2 else 0.3
    fx, fy, cx, cy, s = read_camera(d + "/camera.lua")
    corners_tag = np.array([[-s / 2, s / 2, 0], [s / 2, s / 2, 0], [s / 2, -s / 2, 0],
                            [-s / 2, -s / 2, 0]])
    blocks = {}
    for r in csv.DictReader(open(d + "/truth.csv")):
        blocks[(r["frame"], r["block"])] = {
            "t": np.array([float(r[k]) for k in "xyz"]), "faces": int(r["faces_visible"]),
            "points": [], "observed": []}
    tags = list(csv.DictReader(open(d + "/truth_tags.csv")))
    rows = list(csv.DictReader(open(d + "/corners.csv")))
    assert len(tags) == len(rows), "truth_tags.csv and corners.csv differ in length"
    for tag, row in zip(tags, rows):
        R = quat_to_matrix(*(float(tag[k]) for k in ("qw", "qx", "qy", "qz")))
        t = np.array([float(tag[k]) for k in "xyz"])
        b = blocks[(tag["frame"], tag["block"])]
        b["points"].extend(list((R @ corners_tag.T).T + t))
        b["observed"].extend(float(row[k]) for k in ("u1", "v1", "u2", "v2", "u3", "v3", "u4",
                                                     "v4"))

    def project(P):
        return np.c_[fx * P[:, 0] / P[:, 2] + cx, fy * P[:, 1] / P[:, 2] + cy].ravel()

    rng = np.random.default_rng(0)
    fitted, bound = {1: [], 2: []}, {1: [], 2: []}
    for b in blocks.values():
        offsets, t = np.array(b["points"]) - b["t"], b["t"]
        observed = np.array(b["observed"])

        def residual(p):
            return project((rotation_vector(p[:3]) @ offsets.T).T + t + p[3:]) - observed

        def jacobian(p):
            J = np.zeros((len(observed), 6))
            for i in range(6):
                h = np.zeros(6)
                h[i] = 1e-7
                J[:, i] = (residual(p + h) - residual(p - h)) / 2e-7
            return J

        p = np.zeros(6)
        for _ in range(20):
            step = np.linalg.lstsq(jacobian(p), -residual(p), rcond=None)[0]
            p = p + step
            if np.linalg.norm(step) < 1e-12:
                break
        k = 2 if b["faces"] >= 2 else 1
        fitted[k].append(np.linalg.norm(p[3:]) * 1000)
        J0 = jacobian(np.zeros(6))
        covariance = sigma ** 2 * np.linalg.inv(J0.T @ J0)[3:, 3:]
        draws = rng.multivariate_normal(np.zeros(3), covariance, size=40)
        bound[k].extend(np.linalg.norm(draws, axis=1) * 1000)
    print("%s: %d blocks, corner noise sigma %g px" % (d, len(blocks), sigma))
    for k, name in ((1, "1 face  "), (2, "2+ faces")):
        print("  %s  least squares (true faces) centre median %.3f mm over %d blocks; "
              "linearised bound median %.3f mm" % (name, np.median(fitted[k]), len(fitted[k]),
                                                   np.median(bound[k])))


if __name__ == "__main__":
    main()
