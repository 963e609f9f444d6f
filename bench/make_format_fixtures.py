#!/usr/bin/python3
"""Write the calibration and field-map fixtures of spec/fixtures/ and their truth files.

    /usr/bin/python3 bench/make_format_fixtures.py [OUT_DIR]     (default: spec/fixtures)

Debian's own Python (/usr/bin/python3) with python3-opencv, python3-numpy and python3-yaml.

* OpenCV files are written by OpenCV itself (cv2.FileStorage, 4.6 on Debian 12) in YAML, XML
  and JSON, with the fields of OpenCV's camera calibration tutorial (out_camera_data.xml: the
  time, board, flags and their comment, fisheye_model, camera_matrix, distortion_coefficients,
  the errors, the extrinsics and image points) and with the short K / D and
  cameraMatrix / distCoeffs names.
* ROS and Kalibr are not installed here: their files are written in the layout those tools
  print (ROS 1 camera_calibration's ost.yaml with numpy's array2string, rostopic echo and
  ros2 topic echo of a CameraInfo), and Kalibr's camchains with PyYAML's yaml.dump, which is
  what Kalibr calls (default_flow_style=None, the older PyYAML default, and the block style of
  PyYAML 5.1 and later).
* The WPILib field map is written with json.dumps as WPILib's files are laid out (2-space
  indent, "ID", "pose" {"translation", "rotation" {"quaternion" {W, X, Y, Z}}}, "field").

calibration/truth.lua and field/truth.lua hold the numbers written, as Python's repr (the
shortest text that reads back as the same double): the specs check that tagpose reads them to
the last bit. Every number written is read back here first from the file's own text, so a
layout that would round a number (ROS's 5 decimals) fails this script, not the specs.
"""

import json
import math
import os
import re
import sys

import cv2
import numpy as np
import yaml

OUT = sys.argv[1] if len(sys.argv) > 1 else "spec/fixtures"
CAL = os.path.join(OUT, "calibration")
FIELD = os.path.join(OUT, "field")

truth = {}


def lua(v):
    """A Python value as Lua source (numbers as repr: exact)."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(float(v)) if isinstance(v, float) else str(v)
    if isinstance(v, str):
        return '"' + v + '"'
    if isinstance(v, (list, tuple)):
        return "{ " + ", ".join(lua(x) for x in v) + " }"
    items = []
    for k in sorted(v):
        key = k if re.match(r"^[A-Za-z_]\w*$", k) else '["' + k + '"]'
        items.append(key + " = " + lua(v[k]))
    return "{ " + ", ".join(items) + " }"


def wrapped(text, indent, width=99):
    """Lua source broken after its commas into lines of at most width columns."""
    lines, line, at = [], "", indent
    for piece in re.split(r"(?<=, )", text):
        if line and len(at) + len(line) + len(piece.rstrip()) > width:
            lines.append(at + line.rstrip())
            line, at = "", indent + "  "
        line += piece
    lines.append(at + line.rstrip())
    return "\n".join(lines)


def expect(file, fx, fy, cx, cy, d, model, fmt, **info):
    truth[file] = dict(fx=fx, fy=fy, cx=cx, cy=cy, d=list(d), model=model, format=fmt, **info)


def numbers_in(text):
    return [float(t) for t in re.findall(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?", text)]


def check_written(path, values):
    """Every value must be in the file's text as a number that reads back exactly."""
    with open(path) as f:
        found = numbers_in(f.read())
    for v in values:
        if not any(x == v and math.copysign(1, x) == math.copysign(1, v) for x in found):
            raise SystemExit("%s: %r is not written exactly" % (path, v))


# --- OpenCV ---------------------------------------------------------------------------------

K_PINHOLE = (1.1476932613597107e+03, 1.1471823305217261e+03, 6.3657148113401484e+02,
             3.6212498407386714e+02)
D_PINHOLE = (-4.1802327176423804e-01, 2.5071524406318753e-01, -1.3126781249738201e-03,
             4.8513291650163389e-04, -9.0784351794612364e-02)
K_FISHEYE = (4.2381692781573853e+02, 4.2414237608251203e+02, 6.4032714297091387e+02,
             4.7951826387317091e+02)
D_FISHEYE = (-3.8710583154186397e-02, 1.6251728837192155e-02, -1.5483923841029918e-02,
             2.7813369082412638e-03)


def kmat(k):
    return np.array([[k[0], 0, k[2]], [0, k[1], k[3]], [0, 0, 1]], dtype=np.float64)


def tutorial(path, fisheye):
    """The fields and order of OpenCV's calibration tutorial (saveCameraParams)."""
    k, d = (K_FISHEYE, D_FISHEYE) if fisheye else (K_PINHOLE, D_PINHOLE)
    rng = np.random.default_rng(7)
    views, points = 3, 4
    fs = cv2.FileStorage(path, cv2.FILE_STORAGE_WRITE)
    fs.write("calibration_time", "Tue 14 Mar 2023 10:21:07 AM CET")
    fs.write("nr_of_frames", views)
    fs.write("image_width", 1280)
    fs.write("image_height", 960 if fisheye else 720)
    fs.write("board_width", 9)
    fs.write("board_height", 6)
    fs.write("square_size", 25.0)
    if fisheye:
        fs.writeComment("flags: +recompute_extrinsic +fix_skew")
        fs.write("flags", 10)
    else:
        fs.writeComment("flags: +fix_principal_point +zero_tangent_dist")
        fs.write("flags", 12)
    fs.write("fisheye_model", 1 if fisheye else 0)
    fs.write("camera_matrix", kmat(k))
    fs.write("distortion_coefficients", np.array(d, dtype=np.float64).reshape(-1, 1))
    fs.write("avg_reprojection_error", 0.39259098975581364)
    fs.write("per_view_reprojection_errors",
             rng.uniform(0.2, 0.6, (views, 1)).astype(np.float32))
    fs.writeComment("a set of 6-tuples (rotation vector + translation vector) for each view")
    fs.write("extrinsic_parameters", rng.normal(0, 1, (views, 6)))
    fs.write("image_points", rng.uniform(0, 700, (views, points, 2)).astype(np.float32))
    fs.release()
    check_written(path, k + d)
    expect(os.path.basename(path), k[0], k[1], k[2], k[3], d,
           "fisheye" if fisheye else "pinhole", "opencv",
           width=1280, height=960 if fisheye else 720,
           distortion_model="equidistant" if fisheye else "plumb_bob",
           ignored=["avg_reprojection_error", "board_height", "board_width",
                    "calibration_time", "extrinsic_parameters", "flags", "image_points",
                    "nr_of_frames", "per_view_reprojection_errors", "square_size"])


def opencv_files():
    for ext in ("xml", "yml", "json"):
        tutorial(os.path.join(CAL, "opencv_tutorial." + ext), False)
        tutorial(os.path.join(CAL, "opencv_tutorial_fisheye." + ext), True)

    # calibrateCamera with CALIB_RATIONAL_MODEL, saved under OpenCV's argument names
    k = (9.1365046861264753e+02, 9.1421624589160821e+02, 6.4106518604315521e+02,
         3.5942398076384362e+02)
    d = (3.9843196143209512e-01, -2.6402190341813203e+00, -3.4127015368102717e-04,
         1.6912340112538412e-04, 1.4972643095734893e+00, 2.8213112209081247e-01,
         -2.4740209419712435e+00, 1.4255530011940725e+00)
    path = os.path.join(CAL, "opencv_rational.xml")
    fs = cv2.FileStorage(path, cv2.FILE_STORAGE_WRITE)
    fs.write("cameraMatrix", kmat(k))
    fs.write("distCoeffs", np.array(d).reshape(1, -1))
    fs.write("rms", 0.2871)
    fs.release()
    check_written(path, k + d)
    expect("opencv_rational.xml", k[0], k[1], k[2], k[3], d, "pinhole", "opencv",
           distortion_model="rational_polynomial", ignored=["rms"])

    # K and D of 14 coefficients (the tilted model's, its extra terms 0), in JSON
    k = (6.0123456789012345e+02, 6.0198765432109876e+02, 3.1987654321098765e+02,
         2.4012345678901234e+02)
    d = (-2.8340811e-01, 7.395907e-02, 1.9359e-04, 1.76187114e-05, -1.0e-03, 1.2e-04, -3.4e-05,
         5.6e-06) + (0.0,) * 6
    path = os.path.join(CAL, "opencv_kd14.json")
    fs = cv2.FileStorage(path, cv2.FILE_STORAGE_WRITE)
    fs.write("K", kmat(k))
    fs.write("D", np.array(d).reshape(-1, 1))
    fs.release()
    check_written(path, k + d)
    expect("opencv_kd14.json", k[0], k[1], k[2], k[3], d[:8], "pinhole", "opencv",
           distortion_model="rational_polynomial", ignored=[])

    # single-precision matrices (dt: f), numbers a float holds exactly
    k = (500.25, 501.75, 320.5, 240.125)
    d = (-0.25, 0.0625, 0.0009765625, -0.00048828125, 0.015625)
    path = os.path.join(CAL, "opencv_float.xml")
    fs = cv2.FileStorage(path, cv2.FILE_STORAGE_WRITE)
    fs.write("camera_matrix", kmat(k).astype(np.float32))
    fs.write("distortion_coefficients", np.array(d, dtype=np.float32).reshape(1, -1))
    fs.release()
    check_written(path, k + d)
    expect("opencv_float.xml", k[0], k[1], k[2], k[3], d, "pinhole", "opencv",
           distortion_model="plumb_bob", ignored=[])


# --- ROS --------------------------------------------------------------------------------------

def array_text(values, cols):
    """A matrix as ROS 1's cameracalibrator saves it: numpy's array2string, 5 decimals."""
    m = np.array(values, dtype=np.float64).reshape(-1, cols)
    text = np.array2string(m, precision=5, suppress_small=True, separator=", ")
    return "[" + text.replace("[", "").replace("]", "").replace("\n", "\n        ") + "]"


def ros_files():
    k = (1203.36781, 1205.54308, 652.91826, 368.02017)
    d = (0.11196, -0.17345, 0.00211, 0.00081, 0.0)
    p = (1210.17285, 0.0, 655.12347, 0.0, 0.0, 1212.04907, 369.51176, 0.0, 0.0, 0.0, 1.0, 0.0)
    kflat = (k[0], 0, k[2], 0, k[1], k[3], 0, 0, 1)
    lines = ["image_width: 1280", "image_height: 720", "camera_name: head_camera",
             "camera_matrix:", "  rows: 3", "  cols: 3", "  data: " + array_text(kflat, 3),
             "distortion_model: plumb_bob", "distortion_coefficients:", "  rows: 1",
             "  cols: 5", "  data: " + array_text(d, 5), "rectification_matrix:", "  rows: 3",
             "  cols: 3", "  data: " + array_text((1, 0, 0, 0, 1, 0, 0, 0, 1), 3),
             "projection_matrix:", "  rows: 3", "  cols: 4", "  data: " + array_text(p, 4)]
    path = os.path.join(CAL, "ros1_ost.yaml")
    with open(path, "w") as f:
        f.write("\n".join(lines) + "\n")
    check_written(path, k + d + p)
    expect("ros1_ost.yaml", k[0], k[1], k[2], k[3], d, "pinhole", "ros", width=1280,
           height=720, name="head_camera", distortion_model="plumb_bob", projection=list(p))

    # ROS 2's camera_calibration writes the same layout; here the rational model's 8
    k = (913.6504686126475, 914.2162458916082, 641.0651860431552, 359.4239807638436)
    d = (0.39843, -2.64022, -0.00034, 0.00017, 1.49726, 0.28213, -2.47402, 1.42555)
    k = tuple(round(x, 5) for x in k)
    kflat = (k[0], 0, k[2], 0, k[1], k[3], 0, 0, 1)
    lines = ["image_width: 1280", "image_height: 720", "camera_name: oak_rgb",
             "camera_matrix:", "  rows: 3", "  cols: 3", "  data: " + array_text(kflat, 3),
             "distortion_model: rational_polynomial", "distortion_coefficients:", "  rows: 1",
             "  cols: 8", "  data: " + array_text(d, 8), "rectification_matrix:", "  rows: 3",
             "  cols: 3", "  data: " + array_text((1, 0, 0, 0, 1, 0, 0, 0, 1), 3),
             "projection_matrix:", "  rows: 3", "  cols: 4",
             "  data: " + array_text(kflat[:3] + (0,) + kflat[3:6] + (0, 0, 0, 1, 0), 4)]
    path = os.path.join(CAL, "ros2_ost_rational.yaml")
    with open(path, "w") as f:
        f.write("\n".join(lines) + "\n")
    check_written(path, k + d)
    expect("ros2_ost_rational.yaml", k[0], k[1], k[2], k[3], d, "pinhole", "ros", width=1280,
           height=720, name="oak_rgb", distortion_model="rational_polynomial")

    # a CameraInfo message: rostopic echo (ROS 1) and ros2 topic echo (ROS 2), full doubles
    k = (615.9258601234567, 617.1336670987654, 320.57844212345675, 240.21386198765432)
    d = (0.11190612345678901, -0.17345109876543211, 0.0021141234567890123,
         0.00081309876543210987, 0.0)
    kflat = (k[0], 0.0, k[2], 0.0, k[1], k[3], 0.0, 0.0, 1.0)
    r = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0)
    p = (626.3574829101562, 0.0, 321.2700653076172, 0.0, 0.0, 628.1765747070312,
         240.57393493652344, 0.0, 0.0, 0.0, 1.0, 0.0)
    fl = lambda xs: "[" + ", ".join(repr(float(x)) for x in xs) + "]"
    ros1 = ["header: ", "  seq: 2117", "  stamp: ", "    secs: 1678785667",
            "    nsecs: 482012987", '  frame_id: "camera_color_optical_frame"', "height: 480",
            "width: 640", 'distortion_model: "plumb_bob"', "D: " + fl(d), "K: " + fl(kflat),
            "R: " + fl(r), "P: " + fl(p), "binning_x: 0", "binning_y: 0", "roi: ",
            "  x_offset: 0", "  y_offset: 0", "  height: 0", "  width: 0",
            "  do_rectify: False", "---"]
    path = os.path.join(CAL, "ros1_camera_info.yaml")
    with open(path, "w") as f:
        f.write("\n".join(ros1) + "\n")
    check_written(path, k + d + p)
    expect("ros1_camera_info.yaml", k[0], k[1], k[2], k[3], d, "pinhole", "camera_info",
           width=640, height=480, name="camera_color_optical_frame",
           distortion_model="plumb_bob", projection=list(p))
    block = lambda key, xs: [key + ":"] + ["- " + repr(float(x)) for x in xs]
    ros2 = ["header:", "  stamp:", "    sec: 1678785667", "    nanosec: 482012987",
            "  frame_id: camera_color_optical_frame", "height: 480", "width: 640",
            "distortion_model: plumb_bob"] + block("d", d) + block("k", kflat) \
        + block("r", r) + block("p", p) + ["binning_x: 0", "binning_y: 0", "roi:",
                                           "  x_offset: 0", "  y_offset: 0", "  height: 0",
                                           "  width: 0", "  do_rectify: false", "---"]
    path = os.path.join(CAL, "ros2_camera_info.yaml")
    with open(path, "w") as f:
        f.write("\n".join(ros2) + "\n")
    check_written(path, k + d + p)
    expect("ros2_camera_info.yaml", k[0], k[1], k[2], k[3], d, "pinhole", "camera_info",
           width=640, height=480, name="camera_color_optical_frame",
           distortion_model="plumb_bob", projection=list(p))


# --- Kalibr -----------------------------------------------------------------------------------

def transform(rvec, t):
    r, _ = cv2.Rodrigues(np.array(rvec, dtype=np.float64))
    m = np.eye(4)
    m[:3, :3], m[:3, 3] = r, t
    return [[float(x) for x in row] for row in m]


def kalibr_files():
    cam0 = dict(camera_model="pinhole",
                intrinsics=[458.6548807207614, 457.2966964634893, 367.2158039615726,
                            248.37534060980727],
                distortion_model="radtan",
                distortion_coeffs=[-0.28340811217029355, 0.07395907389290132,
                                   0.00019359502856909603, 1.7618711454538528e-05],
                resolution=[752, 480], rostopic="/cam0/image_raw", cam_overlaps=[1])
    cam1 = dict(camera_model="pinhole",
                intrinsics=[457.5874266035361, 456.13442556023665, 379.9994465203525,
                            255.2381853862733],
                distortion_model="radtan",
                distortion_coeffs=[-0.28368365, 0.07451284, -0.00010473, -3.555907e-05],
                resolution=[752, 480], rostopic="/cam1/image_raw", cam_overlaps=[0],
                T_cn_cnm1=transform((0.0021, -0.0187, 0.0003), (-0.11007, 0.000399, -0.000853)))
    path = os.path.join(CAL, "kalibr_camchain.yaml")
    with open(path, "w") as f:
        f.write(yaml.dump({"cam0": cam0, "cam1": cam1}, default_flow_style=None))
    for name, cam in (("cam0", cam0), ("cam1", cam1)):
        i = cam["intrinsics"]
        check_written(path, tuple(i) + tuple(cam["distortion_coeffs"]))
        expect("kalibr_camchain.yaml" + ("" if name == "cam0" else ":" + name), i[0], i[1], i[2],
               i[3], cam["distortion_coeffs"], "pinhole", "kalibr", width=752, height=480,
               distortion_model="plumb_bob", camera=name, rostopic=cam["rostopic"])

    eq0 = dict(camera_model="pinhole",
               intrinsics=[190.97847715128717, 190.9733070521226, 254.93170605935475,
                           256.8974428996504],
               distortion_model="equidistant",
               distortion_coeffs=[0.0034823894022493434, 0.0007150348452162257,
                                  -0.0020532361418706202, 0.00020293673591811182],
               resolution=[512, 512], rostopic="/cam0/image_raw", cam_overlaps=[1],
               T_cam_imu=transform((-1.2, 1.2, -1.2), (0.0471, -0.0471, -0.0469)),
               timeshift_cam_imu=-0.004928295416049713)
    eq1 = dict(eq0, resolution=[512, 512], intrinsics=[190.44236969414825, 190.4344384721956, 252.59949716835982,
                                254.91723064636983],
               distortion_coeffs=[0.0034003170790442797, 0.001766278153469831,
                                  -0.00266312569781606, 0.0003299517423931039],
               rostopic="/cam1/image_raw", cam_overlaps=[0],
               T_cam_imu=transform((-1.21, 1.19, -1.2), (-0.0539, -0.0471, -0.0469)),
               T_cn_cnm1=transform((0.001, 0.004, -0.0007), (-0.101, 0.0019, 0.0011)),
               timeshift_cam_imu=-0.004906396248235474)
    path = os.path.join(CAL, "kalibr_camchain_imucam.yaml")
    with open(path, "w") as f:
        f.write(yaml.dump({"cam0": eq0, "cam1": eq1}))
    for name, cam in (("cam0", eq0), ("cam1", eq1)):
        i = cam["intrinsics"]
        check_written(path, tuple(i) + tuple(cam["distortion_coeffs"]) +
                      tuple(sum(cam["T_cam_imu"], [])))
        expect("kalibr_camchain_imucam.yaml" + ("" if name == "cam0" else ":" + name), i[0],
               i[1], i[2], i[3], cam["distortion_coeffs"], "fisheye", "kalibr", width=512,
               height=512, distortion_model="equidistant", camera=name,
               rostopic=cam["rostopic"], T_cam_imu=sum(cam["T_cam_imu"], []),
               timeshift_cam_imu=cam["timeshift_cam_imu"])


# --- WPILib field map -------------------------------------------------------------------------

def quaternion(yaw, pitch=0.0, roll=0.0):
    """Rz(yaw)·Ry(pitch)·Rx(roll) as (W, X, Y, Z), WPILib's Rotation3d(roll, pitch, yaw)."""
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    return (cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy)


def field_file():
    inch = 0.0254
    tags = [  # id, x, y, z (m), yaw, pitch (degrees): a made-up field of FRC's size
        (1, 0.0381, 4.1052 + 0.1 / 3, 57.13 * inch, 0, 0),        # blue wall, facing +x
        (2, 0.0381, 5.5479, 57.13 * inch, 0, 0),
        (3, 16.5793, 4.1052, 57.13 * inch, 180, 0),              # red wall, facing -x
        (4, 8.2706, 0.0, 48.0 * inch, 90, 0),                    # side walls
        (5, 8.2706, 8.2112, 48.0 * inch, -90, 0),
        (6, 4.6490, 4.0347, 12.13 * inch, 120, 30),              # tilted: faces up a little
        (7, 11.9047, 4.0347, 12.13 * inch, 60, -20),             # tilted: faces down
        (8, 3.0 + 1 / 7, 2.0, 0.5, 225, 10),
    ]
    out = []
    for tid, x, y, z, yaw, pitch in tags:
        w, qx, qy, qz = quaternion(math.radians(yaw), math.radians(pitch))
        out.append({"ID": tid, "pose": {"translation": {"x": x, "y": y, "z": z},
                                        "rotation": {"quaternion": {"W": w, "X": qx, "Y": qy,
                                                                    "Z": qz}}}})
    doc = {"tags": out, "field": {"length": 16.541, "width": 8.211}}
    os.makedirs(FIELD, exist_ok=True)
    path = os.path.join(FIELD, "wpilib_field.json")
    with open(path, "w") as f:
        f.write(json.dumps(doc, indent=2) + "\n")
    with open(os.path.join(FIELD, "truth.lua"), "w") as f:
        f.write("-- written by bench/make_format_fixtures.py: the poses wpilib_field.json gives,"
                "\n-- in WPILib's frames (metres)\nreturn {\n")
        for t in out:
            p, q = t["pose"]["translation"], t["pose"]["rotation"]["quaternion"]
            f.write(wrapped("[%d] = %s," % (t["ID"], lua({
                "position": [p["x"], p["y"], p["z"]],
                "quaternion": [q["W"], q["X"], q["Y"], q["Z"]]})), "  ") + "\n")
        f.write("}\n")


def main():
    os.makedirs(CAL, exist_ok=True)
    opencv_files()
    ros_files()
    kalibr_files()
    field_file()
    with open(os.path.join(CAL, "truth.lua"), "w") as f:
        f.write("-- written by bench/make_format_fixtures.py: the numbers each file was written"
                "\n-- with (d: the coefficients in OpenCV's order), as Python's repr\nreturn {\n")
        for name in sorted(truth):
            f.write(wrapped('["%s"] = %s,' % (name, lua(truth[name])), "  ") + "\n")
        f.write("}\n")


main()
