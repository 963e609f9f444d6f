#!/usr/bin/python3
"""Side-by-side check of tagpose against OpenCV's solvePnP on a corner log.

    lua5.4 bin/tagpose-replay DATASET/corners.csv --track --out POSES.csv
    /usr/bin/python3 bench/compare_opencv.py DATASET POSES.csv

DATASET holds corners.csv and camera.lua (the format of bench/dev and
bench/realdata); POSES.csv is the pose log replay.lua wrote for it. For every row it runs
cv2.solvePnP with SOLVEPNP_IPPE_SQUARE and SOLVEPNP_ITERATIVE (the camera's distortion
coefficients passed, object points c1..c4 of the tag frame) and prints how far tagpose's pose is
from each (rotation in degrees, translation in the unit of tag_size and in % of the distance), how
far the two OpenCV solvers are from each other, the RMS reprojection errors (all through the
distortion, by cv2.projectPoints), and the rotation jumps of more than 30 degrees between
consecutive frames of a track (frame and frame + 1, same tag) for each solver.

A measuring tool, not part of the library: it needs Debian's python3-numpy and python3-opencv
(they belong to /usr/bin/python3).
"""
import csv
import math
import re
import sys

import cv2
import numpy as np

FLIP_DEG = 30.0


def read_camera(path):
    text = open(path).read()

    def number(key, default=None):
        m = re.search(r"\b" + key + r"\s*=\s*([-+0-9.eE]+)", text)
        if m:
            return float(m.group(1))
        if default is None:
            sys.exit("no %s in %s" % (key, path))
        return default

    K = np.array([[number("fx"), 0, number("cx")], [0, number("fy"), number("cy")], [0, 0, 1]])
    D = np.array([number(k, 0.0) for k in ("k1", "k2", "p1", "p2", "k3")])
    return K, D, number("tag_size")


def quat_to_matrix(w, x, y, z):
    n = math.sqrt(w * w + x * x + y * y + z * z)
    w, x, y, z = w / n, x / n, y / n, z / n
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def angle_deg(a, b):
    """Geodesic angle between two rotations, accurate for small angles too."""
    d = a.T @ b
    axial = np.array([d[2, 1] - d[1, 2], d[0, 2] - d[2, 0], d[1, 0] - d[0, 1]])
    return math.degrees(math.atan2(np.linalg.norm(axial) / 2, (np.trace(d) - 1) / 2))


def rms_reprojection(R, t, obj, uv, K, D):
    rvec, _ = cv2.Rodrigues(R)
    back, _ = cv2.projectPoints(obj, rvec, t.reshape(3, 1), K, D)
    return math.sqrt(np.mean(np.sum((back.reshape(4, 2) - uv) ** 2, axis=1)))


def percentiles(values):
    if not values:
        return "-"
    v = np.array(values)
    return "%.3g / %.3g / %.3g" % (np.median(v), np.percentile(v, 95), v.max())


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    dataset, poses_path = sys.argv[1].rstrip("/"), sys.argv[2]
    K, D, s = read_camera(dataset + "/camera.lua")
    h = s / 2
    obj = np.array([[-h, h, 0], [h, h, 0], [h, -h, 0], [-h, -h, 0]], dtype=np.float64)
    corners = list(csv.DictReader(open(dataset + "/corners.csv")))
    poses = {(r["frame"], r["tag"]): r for r in csv.DictReader(open(poses_path))}

    stats = {k: [] for k in ("tp_ippe", "tp_iter", "ippe_iter", "t_ippe", "tp_pct",
                             "e_tp", "e_ippe", "e_iter")}
    tracks = {"tagpose": {}, "ippe": {}, "iterative": {}}
    failed = 0
    for row in corners:
        uv = np.array([[float(row["u%d" % i]), float(row["v%d" % i])] for i in range(1, 5)])
        key = (row["frame"], row["tag"])
        p = poses.get(key)
        if not p or p["x"] == "":
            failed += 1
            continue
        R_tp = quat_to_matrix(*(float(p[k]) for k in ("qw", "qx", "qy", "qz")))
        t_tp = np.array([float(p[k]) for k in ("x", "y", "z")])
        found = {}
        for name, flag in (("ippe", cv2.SOLVEPNP_IPPE_SQUARE), ("iterative", cv2.SOLVEPNP_ITERATIVE)):
            ok, rvec, tvec = cv2.solvePnP(obj, uv, K, D, flags=flag)
            found[name] = (cv2.Rodrigues(rvec)[0], tvec.reshape(3)) if ok else None
        if not found["ippe"] or not found["iterative"]:
            continue
        (R_ip, t_ip), (R_it, _) = found["ippe"], found["iterative"]
        stats["tp_ippe"].append(angle_deg(R_tp, R_ip))
        stats["tp_iter"].append(angle_deg(R_tp, R_it))
        stats["ippe_iter"].append(angle_deg(R_ip, R_it))
        stats["t_ippe"].append(np.linalg.norm(t_tp - t_ip))
        stats["tp_pct"].append(100 * np.linalg.norm(t_tp - t_ip) / np.linalg.norm(t_ip))
        stats["e_tp"].append(rms_reprojection(R_tp, t_tp, obj, uv, K, D))
        stats["e_ippe"].append(rms_reprojection(R_ip, t_ip, obj, uv, K, D))
        stats["e_iter"].append(rms_reprojection(R_it, found["iterative"][1], obj, uv, K, D))
        frame, tag = int(row["frame"]), row["tag"]
        for name, R in (("tagpose", R_tp), ("ippe", R_ip), ("iterative", R_it)):
            tracks[name][(frame, tag)] = R

    print("%s: %d rows, %d without a tagpose pose" % (dataset, len(corners), failed))
    print("  (median / p95 / max)")
    print("  rotation tagpose - IPPE_SQUARE (deg)   ", percentiles(stats["tp_ippe"]))
    print("  rotation tagpose - ITERATIVE (deg)     ", percentiles(stats["tp_iter"]))
    print("  rotation IPPE_SQUARE - ITERATIVE (deg) ", percentiles(stats["ippe_iter"]))
    print("  translation tagpose - IPPE (tag units) ", percentiles(stats["t_ippe"]))
    print("  translation tagpose - IPPE (% distance)", percentiles(stats["tp_pct"]))
    print("  RMS reprojection tagpose / IPPE / ITERATIVE (px, median): %.4f / %.4f / %.4f" % (
        np.median(stats["e_tp"]), np.median(stats["e_ippe"]), np.median(stats["e_iter"])))
    e_tp, e_ippe = np.array(stats["e_tp"]), np.array(stats["e_ippe"])
    print("  rows where tagpose's RMS reprojection exceeds IPPE's: %d of %d (by at most %.2g px)" % (
        int((e_tp > e_ippe).sum()), len(e_tp), max(0.0, float((e_tp - e_ippe).max()))))
    for name, rots in tracks.items():
        pairs = flips = 0
        for (frame, tag), R in rots.items():
            prev = rots.get((frame - 1, tag))
            if prev is not None:
                pairs += 1
                flips += angle_deg(prev, R) > FLIP_DEG
        print("  %-9s jumps > %g deg between consecutive frames of a track: %d of %d" % (
            name, FLIP_DEG, flips, pairs))


if __name__ == "__main__":
    main()
