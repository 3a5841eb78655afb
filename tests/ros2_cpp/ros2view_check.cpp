// hfsmc/ros2view.hpp on its own, for tests/test_ros2_views.py: reads lines from stdin and
// prints what the C++ monitor would send, to be compared with hfsmc_ros2view.py's.
//   pose ODOM_HEX                 -> the odometry's pose (a `ros2` subscription's `pose`)
//   scan T_MS SCAN_HEX [ODOM_HEX] -> the `scan` message ("null" when it is none)
//   rate KEY NOW COUNT            -> the rate ("null" until known)
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "hfsmc/ros2view.hpp"

namespace {

std::vector<std::uint8_t> bytes_of(const std::string& hex) {
  std::vector<std::uint8_t> out;
  for (std::size_t i = 0; i + 1 < hex.size(); i += 2)
    out.push_back(static_cast<std::uint8_t>(std::stoi(hex.substr(i, 2), nullptr, 16)));
  return out;
}

}  // namespace

int main() {
  using namespace hfsmc::ros2view;
  Rates rates;
  std::string line;
  while (std::getline(std::cin, line)) {
    std::istringstream in(line);
    std::string what;
    in >> what;
    if (what == "pose") {
      std::string hex;
      in >> hex;
      Pose p;
      std::cout << (odometry_pose(bytes_of(hex), p) ? pose_json(p) : "null") << "\n";
    } else if (what == "scan") {
      long long t = 0;
      std::string scan, odom;
      in >> t >> scan >> odom;
      Pose p;
      const bool has = !odom.empty() && odometry_pose(bytes_of(odom), p);
      const std::string msg = scan_message("robot", "scan", t, bytes_of(scan), has ? &p : nullptr);
      std::cout << (msg.empty() ? "null" : msg) << "\n";
    } else if (what == "rate") {
      std::string key;
      double now = 0;
      long count = 0;
      in >> key >> now >> count;
      const double r = rates.rate(key, now, count);
      std::cout << (std::isnan(r) ? std::string("null") : num(r, 1)) << "\n";
    }
  }
  return 0;
}
