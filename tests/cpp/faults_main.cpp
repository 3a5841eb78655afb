// The C++ `mavlink` driver (templates/cpp/hfsmc/mavlink.hpp) under drone faults,
// driven by tests/test_drone_faults.py: `faults_main PORT` opens the driver on
// udpin:127.0.0.1:PORT and answers one line per request line on stdin, so that
// the test flies it exactly as it flies the Python driver:
//
//   connected | ready | armed        -> 1 or 0
//   mode                             -> the mode's name, `-` before any heartbeat
//   age | alt                        -> heartbeat_age(), altitude() (%.6g; inf, nan)
//   ack NAME                         -> last_ack(NAME), `-` when never sent
//   set_mode M | arm | disarm | land -> 1 when sent (a vehicle is known), else 0
//   takeoff ALT                      -> the same
//   history                          -> what the watcher saw (below), one line
//   quit                             -> exit 0
//
// Each request and each sample reads a fresh snapshot of the driver (docs/recording.md:
// an automaton's instant does the same), under one mutex.
// A watcher thread samples connected(), ready(), armed() and mode() every 2 ms
// and keeps each change with its time since start: `history` prints them as
// `T,CONNECTED,READY,ARMED,MODE` items separated by spaces.
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <map>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "hfsmc/mavlink.hpp"

namespace {

using Clock = std::chrono::steady_clock;

std::string num(double x) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.6g", x);
  return buf;
}

std::string dash(const std::string& s) { return s.empty() ? "-" : s; }

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::cerr << "usage: faults_main PORT\n";
    return 2;
  }
  hfsmc::Mavlink drone("drone", std::string("udpin:127.0.0.1:") + argv[1],
                       std::map<std::string, std::string>{});
  const Clock::time_point start = Clock::now();
  std::mutex history_lock;
  std::vector<std::string> history;
  std::atomic<bool> stop{false};
  std::mutex drone_lock;  // a snapshot and the reads of it, by one thread at a time
  std::thread watcher([&] {
    std::string last;
    while (!stop.load()) {
      std::string now;
      {
        std::lock_guard<std::mutex> lock(drone_lock);
        drone.take_snapshot(0);
        now = std::string(drone.connected() ? "1" : "0") + "," + (drone.ready() ? "1" : "0") + "," +
              (drone.armed() ? "1" : "0") + "," + dash(drone.mode());
      }
      if (now != last) {
        double t = std::chrono::duration<double>(Clock::now() - start).count();
        std::lock_guard<std::mutex> lock(history_lock);
        history.push_back(num(t) + "," + now);
        last = now;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
  });
  std::cout << "ready" << std::endl;
  std::string line;
  int status = 0;
  while (std::getline(std::cin, line)) {
    std::istringstream in(line);
    std::string cmd, arg;
    in >> cmd;
    std::getline(in >> std::ws, arg);
    std::string out;
    std::unique_lock<std::mutex> held(drone_lock);
    drone.take_snapshot(0);
    if (cmd == "connected") {
      out = drone.connected() ? "1" : "0";
    } else if (cmd == "ready") {
      out = drone.ready() ? "1" : "0";
    } else if (cmd == "armed") {
      out = drone.armed() ? "1" : "0";
    } else if (cmd == "mode") {
      out = dash(drone.mode());
    } else if (cmd == "age") {
      out = num(drone.heartbeat_age());
    } else if (cmd == "alt") {
      out = num(drone.altitude());
    } else if (cmd == "ack") {
      out = dash(drone.last_ack(arg));
    } else if (cmd == "set_mode") {
      out = drone.set_mode(arg) ? "1" : "0";
    } else if (cmd == "arm") {
      out = drone.arm() ? "1" : "0";
    } else if (cmd == "disarm") {
      out = drone.disarm() ? "1" : "0";
    } else if (cmd == "land") {
      out = drone.land() ? "1" : "0";
    } else if (cmd == "takeoff") {
      out = drone.takeoff(std::stod(arg)) ? "1" : "0";
    } else if (cmd == "history") {
      std::lock_guard<std::mutex> lock(history_lock);
      for (const std::string& h : history) out += (out.empty() ? "" : " ") + h;
    } else if (cmd == "quit") {
      break;
    } else {
      out = "error: unknown request `" + cmd + "`";
      status = 1;
    }
    held.unlock();
    std::cout << out << std::endl;
  }
  stop.store(true);
  watcher.join();
  drone.close();
  return status;
}
