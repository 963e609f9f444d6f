#!/usr/bin/python3
"""The field benchmark's OpenCV side, and both side by side.

    lua5.4 bench/make_field.lua DIR SEED [options]
    lua5.4 bench/field_solve.lua DIR
    /usr/bin/python3 bench/field_opencv.py DIR [DIR ...] [--map PATH]

For every view of DIR (corners.csv, camera.lua, truth.csv as bench/make_field.lua writes them)
it runs cv2.solvePnP with SOLVEPNP_SQPNP over every corner of every tag seen, then
cv2.solvePnPRefineLM, the object points straight from the WPILib map (a tag's corners at
(0, -s/2, -s/2), (0, s/2, -s/2), (0, s/2, s/2), (0, -s/2, s/2) in WPILib's tag frame: x out of
the face, y to the viewer's right, z up; nothing of tagpose's tag frame), and puts the camera on
the field (-R^T t). It reads tagpose's cameras from DIR/tagpose.csv (bench/field_solve.lua) and
prints, for both, the views solved and the camera position error against the truth: median,
95th percentile and views more than 0.5 m off; over all views and by the number of tags seen;
given several sets, for each and for all of them together; and in how many views of two tags
or more each solver reached the lower sum of squared reprojection errors.

A measuring tool, not part of the library: it needs Debian's python3-numpy and python3-opencv
(they belong to /usr/bin/python3).
"""
import csv
import json
import math
import re
import sys
import time

import cv2
import numpy as np


def read_camera(path):
    text = open(path).read()

    def number(key):
        m = re.search(r"\b" + key + r"\s*=\s*([-+0-9.eE]+)", text)
        if not m:
            sys.exit("no %s in %s" % (key, path))
        return float(m.group(1))

    K = np.array([[number("fx"), 0, number("cx")], [0, number("fy"), number("cy")], [0, 0, 1]])
    return K, np.zeros(5), number("tag_size")


def quat_to_matrix(w, x, y, z):
    n = math.sqrt(w * w + x * x + y * y + z * z)
    w, x, y, z = w / n, x / n, y / n, z / n
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def field_corners(path, s):
    """Tag id -> 4x3 corners c1..c4 in the field frame, from WPILib's tag frame."""
    h = s / 2
    out = {}
    for tag in json.load(open(path))["tags"]:
        t, q = tag["pose"]["translation"], tag["pose"]["rotation"]["quaternion"]
        R = quat_to_matrix(q["W"], q["X"], q["Y"], q["Z"])
        c = np.array([t["x"], t["y"], t["z"]])
        local = np.array([[0, -h, -h], [0, h, -h], [0, h, h], [0, -h, h]], dtype=float)
        out[tag["ID"]] = local @ R.T + c
    return out


def read_rows(path):
    with open(path) as f:
        return [{k: float(v) for k, v in row.items()} for row in csv.DictReader(f)]


def squared_error(o, p, R, t, K, D):
    """Sum of squared pixel residuals of object points o at the field -> camera pose R, t."""
    rvec, _ = cv2.Rodrigues(R)
    back, _ = cv2.projectPoints(o, rvec, t.reshape(3, 1), K, D)
    return float(np.sum((back.reshape(-1, 2) - p) ** 2))


def opencv_cameras(dirname, corners, K, D, tagpose_rows):
    """OpenCV's camera on the field per view, its time, and in how many views of two tags or
    more OpenCV's reprojection error is below tagpose's and above it (by 1e-3 px^2)."""
    views = {}
    for row in read_rows(dirname + "/corners.csv"):
        f = int(row["frame"])
        obj, img = views.setdefault(f, ([], []))
        obj.append(corners[int(row["tag"])])
        img.append([[row["u%d" % k], row["v%d" % k]] for k in range(1, 5)])
    out, seconds, lower, higher = {}, 0.0, 0, 0
    for f, (obj, img) in views.items():
        o = np.concatenate(obj).astype(np.float64)
        p = np.concatenate([np.array(i) for i in img]).astype(np.float64)
        t0 = time.perf_counter()
        ok, rvec, tvec = cv2.solvePnP(o, p, K, D, flags=cv2.SOLVEPNP_SQPNP)
        if ok:
            rvec, tvec = cv2.solvePnPRefineLM(o, p, K, D, rvec, tvec)
        seconds += time.perf_counter() - t0
        if ok:
            R, _ = cv2.Rodrigues(rvec)
            out[f] = (-R.T @ tvec).ravel()
            r = tagpose_rows.get(f)
            if len(obj) > 1 and r:
                Rc = quat_to_matrix(r["qw"], r["qx"], r["qy"], r["qz"]).T
                c = np.array([r["x"], r["y"], r["z"]])
                a = squared_error(o, p, Rc, -Rc @ c, K, D)
                b = squared_error(o, p, R, tvec.ravel(), K, D)
                lower += b < a - 1e-3
                higher += b > a + 1e-3
    return out, len(views), seconds, lower, higher


def stats(errors, n):
    if not errors:
        return "%3d/%-3d solved" % (0, n)
    e = np.array(errors)
    return "%3d/%-3d solved  median %.4f m  p95 %.4f m  > 0.5 m: %3d" % (
        len(e), n, np.median(e), np.percentile(e, 95), int(np.sum(e > 0.5)))


def errors_of(dirname, path):
    """Per view: (tags seen, tagpose's error, OpenCV's error or None), and OpenCV's time."""
    K, D, s = read_camera(dirname + "/camera.lua")
    truth = {int(r["frame"]): r for r in read_rows(dirname + "/truth.csv")}
    tp_rows = {int(r["frame"]): r for r in read_rows(dirname + "/tagpose.csv")}
    tp_cams = {f: np.array([r["x"], r["y"], r["z"]]) for f, r in tp_rows.items()}
    cv_cams, n, seconds, lower, higher = opencv_cameras(dirname, field_corners(path, s), K, D,
                                                        tp_rows)
    rows = []
    for f, t in sorted(truth.items()):
        at = np.array([t["x"], t["y"], t["z"]])
        e = [float(np.linalg.norm(c[f] - at)) if f in c else None for c in (tp_cams, cv_cams)]
        rows.append((int(t["tags"]), e[0], e[1]))
    return rows, seconds, lower, higher


def report(name, rows):
    groups = [("all views", lambda k: True), ("1 tag", lambda k: k == 1),
              ("2 tags", lambda k: k == 2), ("3+ tags", lambda k: k >= 3)]
    print("%s: %d views, camera position error against the truth" % (name, len(rows)))
    for group, keep in groups:
        kept = [r for r in rows if keep(r[0])]
        if not kept:
            continue
        for k, solver in ((1, "tagpose"), (2, "OpenCV SQPNP+LM")):
            errors = [r[k] for r in kept if r[k] is not None]
            print("  %-10s %-16s %s" % (group, solver, stats(errors, len(kept))))


def main():
    args = sys.argv[1:]
    path = "bench/field/2024-crescendo.json"
    if len(args) >= 2 and args[-2] == "--map":
        path, args = args[-1], args[:-2]
    if not args or any(a.startswith("-") for a in args):
        sys.exit(__doc__)
    pooled, seconds, lower, higher = [], 0.0, 0, 0
    for dirname in args:
        rows, t, lo, hi = errors_of(dirname.rstrip("/"), path)
        report(dirname.rstrip("/"), rows)
        pooled += rows
        seconds, lower, higher = seconds + t, lower + lo, higher + hi
    if len(args) > 1:
        report("all %d sets" % len(args), pooled)
    print("  views of two tags or more: OpenCV's reprojection error below tagpose's in %d, "
          "above it in %d" % (lower, higher))
    print("  OpenCV: %.0f us per view (solvePnP SQPNP + solvePnPRefineLM, from Python)"
          % (1e6 * seconds / len(pooled)))


if __name__ == "__main__":
    main()
