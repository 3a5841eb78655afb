// hfsmc/ros2view.hpp: a `ros2` interface as the live views show it (schemas/monitor.md,
// minor version 3). Copied unchanged into every C++ component with a ros2 interface; the
// twin of hfsmc_ros2view.py. The interface's Feed (hfsmc_ros2_interface.cpp) makes its
// `ros2` message about 4 times a second from what the node holds (Node::views(), never
// the instant's snapshot), and a `scan` message for a LaserScan subscription's new scan
// (only while a viewer asked for scans). The odometry's pose and the scan's rays are read
// from the samples' CDR bytes, so that no message type needs to be generated for them.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <deque>
#include <limits>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "hfsmc/cdr.hpp"
#include "hfsmc/json.hpp"

namespace hfsmc {
namespace ros2view {

constexpr double RATE_WINDOW_S = 2.0;  // a rate is the messages of about the last 2 s per second
constexpr const char* ODOMETRY = "nav_msgs/msg/Odometry";
constexpr const char* LASER_SCAN = "sensor_msgs/msg/LaserScan";
constexpr std::size_t MAX_RAYS = 1440;  // a scan with more rays is sent every k-th ray

/// Per key, messages per second over about the last RATE_WINDOW_S seconds.
class Rates {
 public:
  /// The rate of `key` whose total is `count` at `now` (steady seconds); NaN until two
  /// counts some time apart are known.
  double rate(const std::string& key, double now, long count) {
    auto& seen = seen_[key];
    if (!seen.empty() && count < seen.back().second) seen.clear();  // a new count from 0
    seen.emplace_back(now, count);
    while (seen.size() > 2 && now - seen[1].first >= RATE_WINDOW_S) seen.pop_front();
    const auto [t0, c0] = seen.front();
    if (now - t0 < 0.2) return std::numeric_limits<double>::quiet_NaN();
    return std::nearbyint(static_cast<double>(count - c0) / (now - t0) * 10.0) / 10.0;
  }

 private:
  std::map<std::string, std::deque<std::pair<double, long>>> seen_;
};

/// `x` rounded to `digits` decimals (Python's round(): ties to even).
inline double rounded(double x, int digits) {
  const double scale = std::pow(10.0, digits);
  return std::nearbyint(x * scale) / scale;
}

/// `x` rounded to `digits` decimals as JSON (as json.dumps writes it), `null` when it is
/// not finite.
inline std::string num(double x, int digits = 3) {
  const double r = std::isfinite(x) ? rounded(x, digits) : x;
  return std::isfinite(r) ? float_repr(r) : "null";
}

/// The first 64 characters of the UTF-8 text `s` (Python's `str(s)[:64]`).
inline std::string head64(const std::string& s) {
  std::size_t chars = 0;
  for (std::size_t i = 0; i < s.size(); ++i)
    if ((static_cast<unsigned char>(s[i]) & 0xC0) != 0x80 && chars++ == 64) return s.substr(0, i);
  return s;
}

struct Header {
  double stamp = 0;  // s
  std::string frame;
};

inline Header read_header(cdr::Reader& r) {
  Header h;
  const auto sec = r.prim<std::int32_t>();
  const auto nsec = r.prim<std::uint32_t>();
  h.stamp = sec + nsec * 1e-9;
  r.string(h.frame);
  h.frame = head64(h.frame);
  return h;
}

/// An Odometry's pose in its frame: x, y (m), yaw (rad), speed v (m/s), turn w (rad/s).
struct Pose {
  double x = 0, y = 0, yaw = 0, v = 0, w = 0, stamp = 0;
  std::string frame;
};

/// The pose of an Odometry's CDR bytes; false when they do not hold one.
inline bool odometry_pose(const std::vector<std::uint8_t>& bytes, Pose& out) {
  try {
    cdr::Reader r(bytes.data(), bytes.size());
    const Header h = read_header(r);
    std::string child;
    r.string(child);
    double p[7], cov[36], tw[6];
    r.prims(p, 7);
    r.prims(cov, 36);
    r.prims(tw, 6);
    const double qx = p[3], qy = p[4], qz = p[5], qw = p[6];
    out = Pose{p[0], p[1], std::atan2(2.0 * (qw * qz + qx * qy), 1.0 - 2.0 * (qy * qy + qz * qz)),
               tw[0], tw[5], h.stamp, h.frame};
  } catch (const cdr::Malformed&) {
    return false;
  }
  return std::isfinite(out.x) && std::isfinite(out.y);
}

inline std::string pose_json(const Pose& p) {
  return "{\"x\":" + num(p.x) + ",\"y\":" + num(p.y) + ",\"yaw\":" + num(p.yaw, 4) +
         ",\"v\":" + num(p.v) + ",\"w\":" + num(p.w) + ",\"frame\":" + json_string(p.frame) + "}";
}

/// The odometry's pose taken back (or on) to `stamp` with its own twist, so that a scan
/// is drawn where the robot was when it was taken; stamps more than 1 s apart (a
/// publisher without a clock) are taken as equal. From the pose as sent (rounded), as
/// hfsmc_ros2view.pose_at computes it.
inline Pose pose_at(Pose p, double stamp) {
  double dt = p.stamp - stamp;
  if (!std::isfinite(dt) || std::abs(dt) > 1.0) dt = 0.0;
  const auto sent = [](double x, int digits) { return std::isfinite(x) ? rounded(x, digits) : 0.0; };
  const double yaw = sent(p.yaw, 4), v = sent(p.v, 3), w = sent(p.w, 3);
  const double back = yaw - w * dt, mid = (yaw + back) / 2;
  p.x = rounded(p.x, 3) - v * std::cos(mid) * dt;
  p.y = rounded(p.y, 3) - v * std::sin(mid) * dt;
  p.yaw = back;
  return p;
}

/// A `scan` message from a LaserScan's CDR bytes: its ranges (m, to the mm; null where
/// there is no return), every k-th ray when it has more than MAX_RAYS; with `odom`, the
/// pose the scan was taken from. "" when the bytes do not hold a scan.
inline std::string scan_message(const std::string& name, const std::string& subscription,
                                long long t_ms, const std::vector<std::uint8_t>& bytes,
                                const Pose* odom) {
  Header h;
  float f[7];
  std::vector<float> ranges;
  try {
    cdr::Reader r(bytes.data(), bytes.size());
    h = read_header(r);
    r.prims(f, 7);
    ranges.resize(r.count(4));
    r.prims(ranges.data(), ranges.size());
  } catch (const cdr::Malformed&) {
    return "";
  }
  const double lo = f[5], hi = f[6];
  const std::size_t step = std::max<std::size_t>(1, (ranges.size() + MAX_RAYS - 1) / MAX_RAYS);
  const std::string amin = num(f[0], 5), inc = num(static_cast<double>(f[2]) * step, 6);
  if (amin == "null" || inc == "null") return "";
  std::string rays;
  for (std::size_t i = 0; i < ranges.size(); i += step) {
    const double x = ranges[i];
    rays += (rays.empty() ? "" : ",") + (std::isfinite(x) && lo <= x && x <= hi ? num(x) : "null");
  }
  std::string o = "{\"type\":\"scan\",\"t\":" + std::to_string(t_ms) + ",\"name\":" +
                  json_string(name) + ",\"subscription\":" + json_string(subscription) +
                  ",\"frame\":" + json_string(h.frame) + ",\"angle_min\":" + amin +
                  ",\"angle_increment\":" + inc + ",\"range_min\":" + num(lo) +
                  ",\"range_max\":" + num(hi) + ",\"ranges\":[" + rays + "]";
  if (odom != nullptr) o += ",\"pose\":" + pose_json(pose_at(*odom, h.stamp));
  return o + "}";
}

}  // namespace ros2view
}  // namespace hfsmc
