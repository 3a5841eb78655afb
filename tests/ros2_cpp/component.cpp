// A component-side test program of the C++ `ros2` runtime (tests/test_ros2_cpp_dds.py):
// node NAME in namespace NS (distro DISTRO) subscribes `scan` (sensor_data) and publishes
// `cmd_vel`; at each instant (20 ms) it takes a snapshot, and for each new scan prints it
// and answers with a Twist (linear.x = the first range, angular.z = the scan's stamp.sec).
// It stops after SECONDS, or once it has answered WANT scans. A StartError: one line, exit 2.
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <thread>

#include "geometry_msgs/msg/twist.hpp"
#include "hfsmc/ros2.hpp"
#include "sensor_msgs/msg/laser_scan.hpp"

int main(int argc, char** argv) {
  if (argc < 7) {
    std::fprintf(stderr, "usage: component NODE NS DISTRO DOMAIN SECONDS WANT\n");
    return 1;
  }
  hfsmc::ros2::Options o;
  o.node = argv[1];
  o.ns = argv[2];
  o.distro = argv[3];
  o.domain = std::atoi(argv[4]);
  const double seconds = std::atof(argv[5]);
  const long want = std::atol(argv[6]);
  using hfsmc::ros2::Qos;
  std::unique_ptr<hfsmc::ros2::Node> made;
  try {
    made = std::make_unique<hfsmc::ros2::Node>(o);
    hfsmc::ros2::Node& node = *made;
    node.subscribe<sensor_msgs::msg::LaserScan>("scan", "scan", Qos::profile("sensor_data"));
    node.advertise<geometry_msgs::msg::Twist>("cmd_vel", "cmd_vel", Qos::profile("default"));
    node.start();
  } catch (const hfsmc::ros2::StartError& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 2;
  }
  hfsmc::ros2::Node& node = *made;
  std::printf("started %s %s\n", node.topic("scan").c_str(), node.topic("cmd_vel").c_str());
  std::fflush(stdout);
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  long seen = 0;
  int subscribers = -1;
  int publishers = 0;
  long answered = 0;  // twists published: one per instant with a new scan (two scans may
                     // come within one instant, on a loaded machine)
  while (std::chrono::steady_clock::now() < end && answered < want) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    node.take_snapshot();
    if (node.subscribers("cmd_vel") != subscribers) {
      subscribers = node.subscribers("cmd_vel");
      std::printf("subscribers %d\n", subscribers);
      std::fflush(stdout);
    }
    if (node.publishers("scan") != publishers) {  // its reader has matched a writer
      publishers = node.publishers("scan");
      std::printf("publishers %d\n", publishers);
      std::fflush(stdout);
    }
    const auto* scan = node.get<sensor_msgs::msg::LaserScan>("scan");
    if (node.count("scan") == seen || scan == nullptr) continue;
    seen = node.count("scan");
    std::printf("scan count=%ld malformed=%ld publishers=%d frame=%s sec=%d n=%zu r0=%g "
                "age_ok=%d bytes=%zu\n", seen, node.malformed("scan"), node.publishers("scan"),
                scan->header.frame_id.c_str(), scan->header.stamp.sec, scan->ranges.size(),
                scan->ranges.empty() ? -1.0 : scan->ranges[0],
                node.age("scan") >= 0 && node.age("scan") < 5, node.bytes("scan").size());
    std::fflush(stdout);
    geometry_msgs::msg::Twist t;
    t.linear.x = scan->ranges.empty() ? 0.0 : scan->ranges[0];
    t.angular.z = scan->header.stamp.sec;
    node.publish("cmd_vel", t);
    ++answered;
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(300));  // reliable: let the last go out
  std::printf("done seen=%ld\n", seen);
  return 0;
}
