// The C++ drivers of the `mavlink` and `camera` interfaces (templates/cpp/hfsmc),
// driven by tests/test_cpp_drivers.py: `drivers_main SCENARIO ARGS...` runs one
// scenario, prints what it checked on stdout and exits 0, or prints `FAIL: ...`
// and exits 1. Some scenarios wait for a line on stdin: the test acts on the
// simulator (or sends junk) in between.
#include <dirent.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <iostream>
#include <map>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "hfsmc/camera.hpp"
#include "hfsmc/mavlink.hpp"

namespace {

using Clock = std::chrono::steady_clock;
using Options = std::map<std::string, std::string>;
constexpr double kPi = 3.14159265358979323846;

[[noreturn]] void fail(const std::string& what) {
  std::cout << "FAIL: " << what << std::endl;
  std::exit(1);
}

void check(bool ok, const std::string& what) {
  if (!ok) fail(what);
  std::cout << "ok: " << what << std::endl;
}

double since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

/// The drivers' queries read a snapshot (docs/recording.md): take one, as an instant does.
void snap() {
  for (hfsmc::Source* s : hfsmc::sources()) s->take_snapshot(0);
}

bool wait_until(const std::function<bool()>& what, double timeout, double step = 0.01) {
  auto end = Clock::now() + std::chrono::duration<double>(timeout);
  while (Clock::now() < end) {
    snap();
    if (what()) return true;
    std::this_thread::sleep_for(std::chrono::duration<double>(step));
  }
  snap();
  return what();
}

bool refused(const std::string& ack) { return ack == "failed" || ack == "denied"; }

void sleep_s(double s) { std::this_thread::sleep_for(std::chrono::duration<double>(s)); }

std::string udpin(const std::string& port) { return "udpin:127.0.0.1:" + port; }

void wait_for_go(const std::string& prompt) {
  std::cout << prompt << std::endl;
  std::string line;
  if (!std::getline(std::cin, line)) fail("stdin closed while waiting after " + prompt);
}

/// SigBlk of a thread of this process, from /proc.
unsigned long long blocked_signals(const std::string& tid) {
  std::ifstream status("/proc/self/task/" + tid + "/status");
  std::string line;
  while (std::getline(status, line)) {
    if (line.rfind("SigBlk:", 0) == 0) return std::stoull(line.substr(7), nullptr, 16);
  }
  fail("no SigBlk for thread " + tid);
}

/// Everything answers at once without a vehicle; options, threads' signal masks, close.
int offline(const std::string& port) {
  {
    hfsmc::Mavlink drone("drone", udpin(port), Options{{"rate", "fast"}, {"colour", "red"}});
    hfsmc::Camera camera("camera", "63", Options{{"size", "big"}});
    check(!drone.connected() && !drone.ready() && !drone.armed(), "not connected, ready, armed");
    check(std::isinf(drone.heartbeat_age()) && drone.heartbeat_age() > 0, "heartbeat_age inf");
    check(drone.mode().empty(), "mode empty");
    Eigen::Vector3d p = drone.position(), v = drone.velocity();
    check(p.array().isNaN().all() && v.array().isNaN().all() && std::isnan(drone.altitude()) &&
              std::isnan(drone.yaw()),
          "position, velocity, altitude, yaw NaN");
    check(drone.battery() == -1, "battery -1");
    check(drone.last_ack("arm").empty(), "no ack yet");
    check(!drone.arm(), "arm not sent");
    check(!drone.set_velocity(1, 0, 0, 0) && !drone.go_to(1, 2, 3) && !drone.hold(),
          "targets not sent");
    check(drone.last_ack("arm") == "not_sent", "last_ack not_sent");
    try {
      drone.set_mode("HOVER");
      fail("set_mode HOVER did not throw");
    } catch (const std::invalid_argument& e) {
      check(std::string(e.what()).rfind("drone: unknown mode `HOVER` (modes: STABILIZE, ACRO,", 0) == 0,
            std::string("set_mode HOVER throws: ") + e.what());
    }
    sleep_s(0.3);
    check(camera.frame().empty() && !camera.ok() && std::isinf(camera.age()) &&
              camera.count() == 0,
          "no frame from device 63");
    // Signals reach only the automaton's thread (this one).
    const unsigned long long wanted = (1ull << (SIGINT - 1)) | (1ull << (SIGTERM - 1));
    const std::string self = std::to_string(::getpid());
    check((blocked_signals(self) & wanted) == 0, "the main thread takes SIGINT and SIGTERM");
    int others = 0;
    DIR* dir = ::opendir("/proc/self/task");
    while (dirent* e = ::readdir(dir)) {
      std::string tid = e->d_name;
      if (tid == "." || tid == ".." || tid == self) continue;
      ++others;
      check((blocked_signals(tid) & wanted) == wanted, "thread " + tid + " blocks SIGINT, SIGTERM");
    }
    ::closedir(dir);
    check(others >= 2, "a reader and a grabber run");
    auto t = Clock::now();
    drone.close();
    camera.close();
    check(since(t) < 0.5, "close is prompt (" + std::to_string(since(t)) + " s)");
  }
  // The port is free again: a second driver binds it.
  hfsmc::Mavlink again("drone", udpin(port), Options{});
  return 0;
}

/// A taken port: said on stderr, exit status 1.
int taken(const std::string& port) {
  hfsmc::Mavlink drone("drone", udpin(port), Options{});
  fail("opened a taken port");
}

/// The simulator's flight: arm refused outside GUIDED, take-off, goto, land, disarm.
int flight(const std::string& port) {
  hfsmc::Mavlink drone("drone", udpin(port), Options{});
  check(wait_until([&] { return drone.connected(); }, 15), "connected");
  check(wait_until([&] { return drone.ready(); }, 10), "ready");
  check(drone.heartbeat_age() < 1.5, "heartbeat fresh");
  check(wait_until([&] { return !std::isnan(drone.yaw()) && drone.battery() >= 0; }, 3),
        "telemetry");
  check(drone.mode() == "STABILIZE" && !drone.armed(), "STABILIZE, disarmed");
  check(drone.arm(), "arm sent");
  check(wait_until([&] { return refused(drone.last_ack("arm")); }, 5), "arm refused outside GUIDED");
  check(!drone.armed(), "still disarmed");
  check(drone.set_mode("guided"), "set_mode sent");
  check(wait_until([&] { return drone.mode() == "GUIDED"; }, 5), "GUIDED");
  check(drone.last_ack("set_mode") == "accepted", "set_mode accepted");
  drone.arm();
  check(wait_until([&] { return drone.armed(); }, 5), "armed");
  drone.takeoff(3.0);
  check(wait_until([&] { return drone.last_ack("takeoff") == "accepted"; }, 5), "takeoff accepted");
  check(wait_until([&] { return drone.altitude() > 2.8; }, 15), "climbed past 2.8 m");
  sleep_s(1.0);
  snap();
  double alt = drone.altitude();
  check(alt > 2.7 && alt < 3.3 && std::abs(drone.position().z() + 3.0) < 0.4,
        "holds 3 m: " + std::to_string(alt));
  check(drone.go_to(4.0, 0.0, 3.0), "goto sent");
  check(wait_until([&] { return std::abs(drone.position().x() - 4.0) < 0.5; }, 15),
        "reached 4 m north");
  check(drone.hold(), "hold sent");
  check(hfsmc::warning_at_stop(drone).rfind(
            "WARNING: ARMED in GUIDED at ", 0) == 0,
        "armed in the air: the warning at stop names mode and altitude");
  check(drone.land(), "land sent");
  check(wait_until([&] { return !drone.armed(); }, 25, 0.1), "landed and disarmed");
  check(drone.mode() == "LAND" && drone.altitude() < 0.3, "LAND mode on the ground");
  check(hfsmc::warning_at_stop(drone).empty(), "disarmed: no warning at stop");
  check(drone.connected(), "still connected");
  return 0;
}

/// The simulator drops the link (--drop-link-after): seen, then back.
int linkloss(const std::string& port) {
  hfsmc::Mavlink drone("drone", udpin(port), Options{});
  check(wait_until([&] { return drone.connected(); }, 15), "connected");
  check(wait_until([&] { return !drone.connected(); }, 15), "link lost");
  check(drone.heartbeat_age() >= 2.0 && drone.heartbeat_age() < 3.0,
        "heartbeat_age " + std::to_string(drone.heartbeat_age()));
  double age = drone.heartbeat_age();
  sleep_s(0.5);
  snap();
  check(drone.heartbeat_age() >= age + 0.45, "heartbeat_age grows");
  check(wait_until([&] { return drone.connected(); }, 15), "link back");
  check(drone.heartbeat_age() < 1.5, "heartbeat fresh again");
  return 0;
}

/// `hfsmc sim --autopilot px4` (docs/interfaces.md, "PX4 and ArduPilot"): arming refused
/// with a text in two chunks, PX4's mode names, GUIDED as Hold on the ground, a target
/// set once streamed by the driver, DO_SET_MODE's second answer, and a failsafe (the test
/// drops the link) the driver does not fight.
int px4(const std::string& port) {
  hfsmc::Mavlink drone("drone", udpin(port), Options{});
  check(wait_until([&] { return drone.connected(); }, 15), "connected");
  check(drone.mode() == "HOLD" && !drone.ready(), "PX4's HOLD, not ready yet");
  drone.arm();
  check(wait_until([&] { return drone.last_ack("arm") == "temporarily_rejected"; }, 5),
        "arm refused before the checks pass");
  check(wait_until([&] { return drone.ready(); }, 15), "ready");
  try {
    drone.set_mode("BRAKE");
    fail("BRAKE accepted");
  } catch (const std::invalid_argument& e) {
    check(std::string(e.what()).rfind("drone: PX4 has no mode `BRAKE` (modes: GUIDED, HOLD,", 0) == 0,
          "a mode PX4 lacks throws");
  }
  check(drone.set_mode("guided") && drone.arm() && drone.takeoff(3.0), "GUIDED, arm, takeoff sent");
  check(wait_until([&] { return drone.mode() == "HOLD" && drone.altitude() > 2.8; }, 30),
        "took off, holds");
  drone.set_mode("PRECLAND");  // the simulator answers ACCEPTED, then DENIED
  check(wait_until([&] { return drone.last_ack("set_mode") == "denied"; }, 5),
        "the second answer counts");
  drone.set_mode("GUIDED");  // in the air: the driver streams a hold, then asks for OFFBOARD
  drone.set_velocity(1.0, 0.0, 0.0, 0.0);  // once
  check(wait_until([&] { return drone.mode() == "GUIDED" && drone.velocity().x() > 0.8; }, 10),
        "OFFBOARD, flying north");
  sleep_s(2.0);  // far longer than PX4's COM_OF_LOSS_T: the driver streams
  snap();
  check(drone.mode() == "GUIDED" && drone.failsafe().empty(), "still OFFBOARD, no failsafe");
  wait_for_go("drop the link");
  check(wait_until([&] { return drone.heartbeat_age() < 1.0 && drone.mode() == "POSCTL"; }, 10),
        "back in POSCTL (the failsafe)");
  sleep_s(2.0);
  snap();
  check(drone.mode() == "POSCTL", "not taken back");
  check(drone.failsafe() == "offboard_lost", "failsafe(): offboard_lost, not " + drone.failsafe());
  check(drone.land(), "land sent");
  snap();
  check(drone.failsafe().empty(), "the model acted: no failsafe left");
  check(wait_until([&] { return drone.mode() == "LAND"; }, 5), "LAND");
  return 0;
}

/// The mission API (docs/interfaces.md, "Missions") on either simulated autopilot: home,
/// goto_location with a heading, set_yaw keeping the target, go_to with a heading, bad
/// input thrown, RTL at 12 m. `target` is "LAT,LON" of a point 12 m north, 9 m east.
int mission(const std::string& port, const std::string& where) {
  const double lat = std::stod(where.substr(0, where.find(','))),
               lon = std::stod(where.substr(where.find(',') + 1));
  hfsmc::Mavlink drone("drone", udpin(port), Options{});
  check(wait_until([&] { return drone.ready() && !std::isnan(drone.home().x()); }, 30), "ready, home");
  check(drone.battery_failsafe().empty(), "no battery failsafe");
  check(!drone.status_text().empty(), "a text: " + drone.status_text());
  check(drone.set_mode("GUIDED") && drone.arm() && drone.takeoff(5.0), "GUIDED, arm, takeoff sent");
  check(wait_until([&] { return drone.altitude() > 4.5; }, 40), "took off");
  check(std::fabs(drone.distance_to_location(lat, lon) - 15.0) < 0.5, "15 m away");
  drone.goto_location(lat, lon, 7.0, kPi / 2);
  check(wait_until([&] { return drone.reached_location(lat, lon, 7.0, 0.5); }, 40), "reached");
  // The same point in local metres: the two conversions differ by centimetres, so the first
  // instant within 0.5 m of one may be just outside the other (the flight settles in 10 s).
  check(wait_until([&] { return drone.reached(12.0, 9.0, 7.0, 0.5) && drone.distance_to(12.0, 9.0) < 0.5; }, 10),
        "reached, locally");
  const auto facing = [&](double h) {
    return std::fabs(std::remainder(drone.yaw() - h, 2 * kPi)) < 0.05;
  };
  check(wait_until([&] { return facing(kPi / 2); }, 10), "faces east");
  drone.set_yaw(kPi);
  check(wait_until([&] { return facing(kPi); }, 10), "faces south");
  check(drone.reached(12.0, 9.0, 7.0, 0.5), "still there");
  drone.go_to(12.0, 9.0, 7.0, -kPi / 2);
  check(wait_until([&] { return facing(-kPi / 2); }, 10), "faces west");
  const std::pair<std::function<void()>, std::string> bad[] = {
      {[&] { drone.goto_location(91.0, lon, 5.0); }, "drone: latitude 91 is out of range -90..90"},
      {[&] { drone.goto_location(lat, -190.0, 5.0); }, "drone: longitude -190 is out of range"},
      {[&] { drone.rtl(-3.0); }, "drone: rtl altitude -3 m is not above home"}};
  for (const auto& [call, message] : bad) {
    try {
      call();
      fail("accepted: " + message);
    } catch (const std::invalid_argument& e) {
      check(std::string(e.what()).rfind(message, 0) == 0, std::string("thrown: ") + e.what());
    }
  }
  check(drone.rtl(12.0), "rtl sent");
  check(wait_until([&] { return drone.mode() == "RTL"; }, 5), "RTL");
  check(wait_until([&] { return drone.altitude() > 11.5; }, 30), "climbs to 12 m");
  check(wait_until([&] { return !drone.armed(); }, 120), "landed, disarmed");
  check(drone.distance_to(0.0, 0.0) < 1.0, "at home");
  return 0;
}

/// Missions (docs/interfaces.md, "Missions"): an upload the vehicle refuses (too many
/// points) is a result, a bad point throws, a mission of three points around home with a
/// heading is flown in AUTO, its progress followed, and it lands at its last point.
int upload(const std::string& port) {
  hfsmc::Mavlink drone("drone", udpin(port), Options{});
  check(wait_until([&] { return drone.ready() && !std::isnan(drone.home().x()); }, 30), "ready, home");
  const Eigen::Vector3d home = drone.home();
  const auto at = [&](double north, double east, double alt) {  // flat earth, as the simulator
    const double r = 6378137.0;
    return std::vector<double>{home.x() + north / r * 180.0 / kPi,
                               home.y() + east / (r * std::cos(home.x() * kPi / 180.0)) * 180.0 / kPi, alt};
  };
  check(drone.upload_mission(std::vector<std::vector<double>>(1001, at(1, 1, 5))), "sent");
  check(wait_until([&] { return drone.last_ack("upload_mission") == "failed"; }, 10), "refused: no space");
  try {
    drone.upload_mission({at(1, 1, 5), {95.0, 0.0, 5.0}});
    fail("a latitude of 95 accepted");
  } catch (const std::invalid_argument& e) {
    check(std::string(e.what()) == "drone: latitude 95 is out of range -90..90 (degrees) (upload_mission point 1)",
          std::string("thrown: ") + e.what());
  }
  check(drone.set_mode("GUIDED") && drone.arm() && drone.takeoff(5.0), "GUIDED, arm, takeoff sent");
  check(wait_until([&] { return drone.altitude() > 4.5; }, 40), "took off");
  std::vector<double> first = at(8, 0, 6);
  first.push_back(kPi / 2);
  check(drone.upload_mission({first, at(8, 8, 5), at(0, 8, 5)}, "land"), "mission sent");
  check(wait_until([&] { return drone.last_ack("upload_mission") == "accepted"; }, 10), "accepted");
  check(drone.mission_progress() == std::make_pair(0, 3), "three points, none reached");
  drone.set_mode("AUTO");
  check(wait_until([&] { return drone.mode() == "AUTO"; }, 5), "AUTO");
  check(wait_until([&] { return drone.mission_progress() == std::make_pair(3, 3); }, 60), "all reached");
  check(wait_until([&] { return !drone.armed(); }, 90), "landed, disarmed");
  check(drone.distance_to(0.0, 8.0) < 1.0, "at the last point");
  return 0;
}

/// Junk datagrams (sent by the test) do not break the reader.
int garbage(const std::string& port) {
  hfsmc::Mavlink drone("drone", udpin(port), Options{});
  check(wait_until([&] { return drone.connected() && !std::isnan(drone.yaw()); }, 15),
        "connected, telemetry");
  wait_for_go("send junk");
  sleep_s(1.5);
  snap();
  check(drone.connected() && drone.heartbeat_age() < 1.5, "heartbeats still read");
  check(drone.mode() == "STABILIZE", "mode unchanged");
  drone.arm();  // STABILIZE: refused, but answered
  check(wait_until([&] { return refused(drone.last_ack("arm")); }, 5), "commands still answered");
  return 0;
}

/// Frames from the simulator's MJPEG stream; a camera drop (SIGUSR2, by the test) and back.
int camera(const std::string& url) {
  hfsmc::Camera camera("camera", url, Options{});
  hfsmc::Camera small("small", url, Options{{"size", "160x120"}});
  check(wait_until([&] { return !camera.frame().empty() && !small.frame().empty(); }, 15),
        "frames arrive");
  cv::Mat f = camera.frame();
  check(f.type() == CV_8UC3 && f.cols >= 160 && f.rows >= 120,
        "BGR frame " + std::to_string(f.cols) + "x" + std::to_string(f.rows));
  check(small.frame().cols == 160 && small.frame().rows == 120, "resized to 160x120");
  check(camera.age() >= 0 && camera.age() < 0.5 && camera.ok(),
        "fresh frame: age " + std::to_string(camera.age()));
  long seen = camera.count();
  check(wait_until([&] { return camera.count() >= seen + 5; }, 3), "frames keep coming");
  small.close();
  wait_for_go("pause the camera");
  check(wait_until([&] { return !camera.ok(); }, 5), "stale once the stream drops");
  cv::Mat last = camera.frame();
  double worst = 0;
  for (int i = 0; i < 200; ++i) {
    auto t = Clock::now();
    (void)camera.frame();
    (void)camera.age();
    (void)camera.ok();
    worst = std::max(worst, since(t));
  }
  check(worst < 0.05, "no wait while down");
  check(camera.frame().data == last.data && camera.age() >= 1.0, "the last frame kept");
  wait_for_go("resume the camera");
  seen = camera.count();
  check(wait_until([&] { return camera.count() > seen && camera.ok(); }, 8), "frames back");
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 3) {
    std::cerr << "usage: drivers_main offline|taken|flight|linkloss|garbage PORT\n"
                 "       drivers_main camera URL\n";
    return 2;
  }
  const std::string scenario = argv[1], arg = argv[2];
  if (scenario == "offline") return offline(arg);
  if (scenario == "taken") return taken(arg);
  if (scenario == "flight") return flight(arg);
  if (scenario == "linkloss") return linkloss(arg);
  if (scenario == "garbage") return garbage(arg);
  if (scenario == "px4") return px4(arg);
  if (scenario.rfind("mission:", 0) == 0) return mission(arg, scenario.substr(8));
  if (scenario == "camera") return camera(arg);
  if (scenario == "upload") return upload(arg);
  std::cerr << "unknown scenario " << scenario << "\n";
  return 2;
}
