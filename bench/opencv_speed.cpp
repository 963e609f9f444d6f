// The speed bar: OpenCV's C++ cv::solvePnPGeneric with SOLVEPNP_IPPE_SQUARE on a data set's
// corners — both poses of the planar ambiguity and their reprojection errors, what a tagpose
// solve returns — timed in-process (no Python), median µs per pose over passes. For the
// same-run comparison with examples/benchmark.lua (bench/speed.sh; see docs/accuracy.md).
//
//   g++ -O2 -o /tmp/opencv_speed bench/opencv_speed.cpp $(pkg-config --cflags --libs opencv4)
//   /tmp/opencv_speed DATASET_DIR [PASSES]
//
// DATASET_DIR holds camera.lua (fx, fy, cx, cy, tag_size, optional distortion k1 k2 p1 p2 k3)
// and corners.csv (frame,tag,u1,v1,...,u4,v4), as bench/dev does.
#include <opencv2/calib3d.hpp>
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

static double field(const std::string &text, const std::string &name, double fallback) {
  std::smatch m;
  std::regex re("\\b" + name + "\\s*=\\s*([-+0-9.eE]+)");
  if (std::regex_search(text, m, re)) return std::stod(m[1]);
  return fallback;
}

int main(int argc, char **argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: opencv_speed DATASET_DIR [PASSES]\n");
    return 2;
  }
  std::string dir = argv[1];
  int passes = argc > 2 ? std::atoi(argv[2]) : 15;
  std::ifstream cf(dir + "/camera.lua");
  std::stringstream cs;
  cs << cf.rdbuf();
  std::string cam = cs.str();
  double fx = field(cam, "fx", 0), fy = field(cam, "fy", 0), cx = field(cam, "cx", 0),
         cy = field(cam, "cy", 0), s = field(cam, "tag_size", 0);
  cv::Mat K = (cv::Mat_<double>(3, 3) << fx, 0, cx, 0, fy, cy, 0, 0, 1);
  cv::Mat D = (cv::Mat_<double>(1, 5) << field(cam, "k1", 0), field(cam, "k2", 0),
               field(cam, "p1", 0), field(cam, "p2", 0), field(cam, "k3", 0));
  if (cv::countNonZero(D) == 0) D = cv::Mat();  // no lens: as PEERS.md's runs pass none
  std::vector<cv::Point3d> object = {{-s / 2, s / 2, 0}, {s / 2, s / 2, 0}, {s / 2, -s / 2, 0},
                                     {-s / 2, -s / 2, 0}};
  std::ifstream in(dir + "/corners.csv");
  std::string line;
  std::getline(in, line);
  std::vector<std::vector<cv::Point2d>> rows;
  while (std::getline(in, line)) {
    std::stringstream ls(line);
    std::string v;
    std::vector<double> f;
    while (std::getline(ls, v, ',')) f.push_back(std::stod(v));
    if (f.size() < 10) continue;
    rows.push_back({{f[2], f[3]}, {f[4], f[5]}, {f[6], f[7]}, {f[8], f[9]}});
  }
  std::vector<cv::Mat> rvecs, tvecs;
  cv::Mat errors;
  std::vector<double> us;
  double sink = 0;
  for (int p = 0; p <= passes; p++) {
    auto t0 = std::chrono::steady_clock::now();
    for (auto &r : rows) {
      cv::solvePnPGeneric(object, r, K, D, rvecs, tvecs, false, cv::SOLVEPNP_IPPE_SQUARE,
                          cv::noArray(), cv::noArray(), errors);
      sink += tvecs[0].at<double>(2) + static_cast<double>(errors.total());
    }
    auto t1 = std::chrono::steady_clock::now();
    if (p > 0)  // the first pass warms up
      us.push_back(std::chrono::duration<double, std::micro>(t1 - t0).count() / rows.size());
  }
  std::sort(us.begin(), us.end());
  std::printf("opencv %s solvePnPGeneric IPPE_SQUARE (both poses and errors): %.2f us/pose "
              "(median of %d passes over %zu rows; min %.2f, max %.2f)%s\n",
              CV_VERSION, us[us.size() / 2], passes, rows.size(), us.front(), us.back(),
              sink == 0 ? "" : "");
  return 0;
}
