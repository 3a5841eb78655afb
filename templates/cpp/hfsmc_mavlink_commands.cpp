// hfsmc_mavlink_commands.cpp: the commands of the `mavlink` interface (hfsmc/mavlink.hpp),
// compiled into the library hfsmc_mavlink beside hfsmc_mavlink.cpp: each is told to the
// recording or the playback through the driver base (tell()), then sent as a
// COMMAND_LONG or a position target; the reader thread matches the COMMAND_ACKs to the
// commands waiting (resent once halfway, given up at the deadline), which last_ack() says.
//
// The mavgen headers are included with -Waddress-of-packed-member (they take
// the address of packed fields everywhere) and -Wpedantic (anonymous structs)
// off: g++ 12 gives them no other warning with -Wall -Wextra, so they build with
// -Werror whether the include folder is given with -I or -isystem.
#include <arpa/inet.h>
#include <fcntl.h>
#include <netdb.h>
#include <netinet/in.h>
#include <poll.h>
#include <pthread.h>
#include <signal.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <initializer_list>
#include <limits>
#include <map>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Waddress-of-packed-member"
#pragma GCC diagnostic ignored "-Wpedantic"
#include "mavlink/ardupilotmega/mavlink.h"
#pragma GCC diagnostic pop

#include "hfsmc/mavlink.hpp"

namespace hfsmc {

// -- commands (send and return; true when sent, i.e. a vehicle is known) ---------
/// Ask for a flight mode by name (MAV_CMD_DO_SET_MODE with the custom mode).
/// An unknown name throws std::invalid_argument (Python: ValueError).
bool Mavlink::set_mode(const std::string& name) {
  std::string wanted = upper(strip(name));
  if (current().autopilot == px4::kAutopilotPx4) {  // PX4's names: px4.hpp
    uint32_t number = 0;
    if (!px4::mode_number(name, &number))
      throw std::invalid_argument(this->name() + ": PX4 has no mode `" + name + "` (modes: " + px4::mode_list() + ")");
    tell("set_mode", "[" + json_string(name) + "]");
    if (!live()) return command("set_mode", "set_mode " + wanted, MAV_CMD_DO_SET_MODE, {});
    return px4_mode(wanted, number);
  }
  const ModeTable table = modes(static_cast<uint8_t>(current().type));
  const Mode* found = nullptr;
  std::string names;
  for (const Mode* m = table.first; m != table.second; ++m) {
    if (wanted == m->name) found = m;
    names += (names.empty() ? "" : ", ") + std::string(m->name);
  }
  if (found == nullptr) {
    throw std::invalid_argument(this->name() + ": unknown mode `" + name + "` (modes: " + names + ")");
  }
  tell("set_mode", "[" + json_string(name) + "]");
  return command("set_mode", "set_mode " + wanted, MAV_CMD_DO_SET_MODE,
                 {MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, static_cast<float>(found->number)});
}

/// Arm the motors (MAV_CMD_COMPONENT_ARM_DISARM 1).
bool Mavlink::arm() {
  tell("arm", "[]");
  return command("arm", "arm", MAV_CMD_COMPONENT_ARM_DISARM, {1});
}

/// Disarm the motors (MAV_CMD_COMPONENT_ARM_DISARM 0; the vehicle refuses in flight).
bool Mavlink::disarm() {
  tell("disarm", "[]");
  return command("disarm", "disarm", MAV_CMD_COMPONENT_ARM_DISARM, {0});
}

/// Climb to `alt` m above home (MAV_CMD_NAV_TAKEOFF; GUIDED and armed).
bool Mavlink::takeoff(double alt) {
  tell("takeoff", "[" + json_number(alt) + "]");
  takeoff_alt_ = alt;  // PX4 adds home's altitude AMSL to the double, as Python does
  return command("takeoff", "takeoff", MAV_CMD_NAV_TAKEOFF,
                 {0, 0, 0, 0, 0, 0, static_cast<float>(alt)});
}

/// Land where the vehicle is (MAV_CMD_NAV_LAND: LAND mode).
bool Mavlink::land() {
  tell("land", "[]");
  return command("land", "land", MAV_CMD_NAV_LAND, {});
}

/// Stop where the vehicle is: a zero velocity target (GUIDED).
bool Mavlink::hold() {
  tell("hold", "[]");
  aim_ = Aim{};
  return target_local(MAV_FRAME_BODY_OFFSET_NED, kVelocityMask, {0, 0, 0}, {0, 0, 0}, 0);
}

/// Velocity target in the body frame: m/s forward, right, down; rad/s clockwise.
/// ArduPilot stops the vehicle when no new target comes for 3 s.
bool Mavlink::set_velocity(double vx, double vy, double vz, double yaw_rate) {
  tell("set_velocity", "[" + json_number(vx) + "," + json_number(vy) + "," + json_number(vz) + "," +
                           json_number(yaw_rate) + "]");
  aim_ = Aim{};
  return target_local(MAV_FRAME_BODY_OFFSET_NED, kVelocityMask, {0, 0, 0}, {vx, vy, vz},
                      yaw_rate);
}

// -- sending ----------------------------------------------------------------------
bool Mavlink::target(uint8_t* system, uint8_t* component) const {
  std::lock_guard<std::mutex> lock(state_);
  *system = s_.target_system;
  *component = s_.target_component;
  return s_.target_seen;
}

uint8_t Mavlink::vehicle_type() const {
  std::lock_guard<std::mutex> lock(state_);
  return s_.type;
}

/// A COMMAND_LONG: sent when a vehicle has been heard (the snapshot says so; the
/// reader thread's own, `quiet`, ask the state at hand), its outcome awaited.
bool Mavlink::command(const std::string& name, const std::string& label, uint16_t cmd,
             std::initializer_list<float> params, bool quiet) {
  Pending p{name, label, cmd, {0, 0, 0, 0, 0, 0, 0}, {}, {}, true, quiet};
  std::copy(params.begin(), params.end(), p.params);
  if (offboard_ && (name == "set_mode" || name == "land" || name == "rtl" || name == "takeoff"))
    offboard_->clear_lost();  // the model acts on it
  if (!quiet) {
    instant().acks[name] = current().vehicle ? "pending" : "not_sent";
    if (!live() || !current().vehicle) {
      if (!current().vehicle) say(label + ": not sent, no vehicle yet (no heartbeat)");
      if (live()) {
        std::lock_guard<std::mutex> lock(link_);
        acks_[name] = "not_sent";
      }
      return current().vehicle;
    }
  }
  return send_long(p);
}

/// The sending part of command(), from any thread (the snapshot untouched).
bool Mavlink::send_long(Pending p) {
  uint8_t system = 0, component = 0;
  bool known = target(&system, &component);
  if (known && px4() && !px4_command(p)) return false;
  {
    std::lock_guard<std::mutex> lock(link_);
    if (known) {
      send_command(system, component, p, 0);
      Clock::time_point now = this->now();
      p.deadline = now + duration(ack_timeout_);
      p.resend_at = now + duration(ack_timeout_ / 2);
      pending_.push_back(p);
    }
    if (!p.quiet) acks_[p.name] = known ? "pending" : "not_sent";
  }
  if (!known) say(p.label + ": not sent, no vehicle yet (no heartbeat)");
  return known;
}

void Mavlink::send_command(uint8_t system, uint8_t component, const Pending& p, uint8_t confirmation) {
  mavlink_message_t msg;
  mavlink_msg_command_long_pack_status(sysid_, kGcsComponent, tx_status(), &msg, system,
                                       component, p.command, confirmation, p.params[0],
                                       p.params[1], p.params[2], p.params[3], p.params[4],
                                       p.params[5], p.params[6]);
  send(msg);
}

bool Mavlink::target_local(uint8_t frame, uint16_t mask, Eigen::Vector3d pos, Eigen::Vector3d vel,
                  double yaw_rate, double yaw) {
  if (!current().vehicle) return false;  // a stream of targets: nothing to say
  uint8_t system, component;
  if (!live() || !target(&system, &component)) return true;
  const bool on_px4 = px4();
  if (on_px4 && frame == MAV_FRAME_BODY_OFFSET_NED) frame = px4::kFrameBodyNed;  // turned by the heading
  px4::Target t;
  t.frame = frame;
  t.mask = mask;
  for (int i = 0; i < 3; ++i) {
    t.pos[i] = pos[i];
    t.vel[i] = vel[i];
  }
  t.yaw_rate = yaw_rate;
  t.yaw = yaw;
  send_target(t);
  if (on_px4) offboard_->target(now_s(), t);
  return true;
}

void Mavlink::send_target(const px4::Target& t) {  // SET_POSITION_TARGET_LOCAL_NED, any thread
  uint8_t system, component;
  if (!target(&system, &component)) return;
  auto boot_ms = static_cast<uint32_t>(
      std::chrono::duration_cast<std::chrono::milliseconds>(now() - start_).count());
  std::lock_guard<std::mutex> lock(link_);
  mavlink_message_t msg;
  if (t.global) {  // lat, lon in degE7; the altitude above home
    mavlink_msg_set_position_target_global_int_pack_status(
        sysid_, kGcsComponent, tx_status(), &msg, boot_ms, system, component, t.frame,
        t.mask, static_cast<int32_t>(std::nearbyint(t.pos[0] * 1e7)),
        static_cast<int32_t>(std::nearbyint(t.pos[1] * 1e7)), static_cast<float>(t.pos[2]), 0, 0,
        0, 0, 0, 0, static_cast<float>(t.yaw), 0);
    send(msg);
    return;
  }
  mavlink_msg_set_position_target_local_ned_pack_status(
      sysid_, kGcsComponent, tx_status(), &msg, boot_ms, system, component, t.frame, t.mask,
      static_cast<float>(t.pos[0]), static_cast<float>(t.pos[1]), static_cast<float>(t.pos[2]),
      static_cast<float>(t.vel[0]), static_cast<float>(t.vel[1]), static_cast<float>(t.vel[2]),
      0, 0, 0, static_cast<float>(t.yaw), static_cast<float>(t.yaw_rate));
  send(msg);
}

void Mavlink::send_rtl_altitude(double alt) {  // a PARAM_SET: RTL_ALT in cm, PX4's in m
  uint8_t system, component;
  if (!target(&system, &component)) return;
  const bool on_px4 = px4();
  const char* name = on_px4 ? "RTL_RETURN_ALT" : "RTL_ALT";
  const double value = on_px4 ? alt : std::nearbyint(alt * 100);
  {
    std::lock_guard<std::mutex> lock(link_);
    mavlink_message_t msg;
    char id[16] = {};  // mavgen copies all 16 bytes: a padded buffer, not the literal
    std::strncpy(id, name, sizeof id);
    mavlink_msg_param_set_pack_status(sysid_, kGcsComponent, tx_status(), &msg, system,
                                      component, id, static_cast<float>(value),
                                      on_px4 ? MAV_PARAM_TYPE_REAL32 : MAV_PARAM_TYPE_INT16);
    send(msg);
  }
  say(std::string("rtl: ") + name + " set to " + fmt(value));
}

void Mavlink::request_rates() {
  const double fast = 1e6 / std::max(rate_, 0.1);
  const double slow = 1e6 / kSlowRateHz;
  const std::pair<const char*, std::pair<uint32_t, double>> rates[] = {
      {"LOCAL_POSITION_NED", {MAVLINK_MSG_ID_LOCAL_POSITION_NED, fast}},
      {"GLOBAL_POSITION_INT", {MAVLINK_MSG_ID_GLOBAL_POSITION_INT, fast}},
      {"ATTITUDE", {MAVLINK_MSG_ID_ATTITUDE, fast}},
      {"SYS_STATUS", {MAVLINK_MSG_ID_SYS_STATUS, slow}},
      {"GPS_RAW_INT", {MAVLINK_MSG_ID_GPS_RAW_INT, slow}},
      {"BATTERY_STATUS", {MAVLINK_MSG_ID_BATTERY_STATUS, slow}},
      {"HOME_POSITION", {MAVLINK_MSG_ID_HOME_POSITION, 1e6 / kHomeRateHz}},
      {"EKF_STATUS_REPORT", {MAVLINK_MSG_ID_EKF_STATUS_REPORT, slow}},
  };
  for (const auto& r : rates) {
    if (px4() && r.second.first == MAVLINK_MSG_ID_EKF_STATUS_REPORT) continue;  // PX4 has none
    command("set_message_interval", std::string("set_message_interval ") + r.first,
            MAV_CMD_SET_MESSAGE_INTERVAL,
            {static_cast<float>(r.second.first),
             static_cast<float>(std::nearbyint(r.second.second))},
            true);
  }
}

/// The oldest command of that id waiting gets the answer (acks come in order).
void Mavlink::on_ack(const mavlink_message_t& msg) {
  mavlink_command_ack_t ack;
  mavlink_msg_command_ack_decode(&msg, &ack);
  std::string label, result;
  bool quiet = false;
  {
    std::lock_guard<std::mutex> lock(link_);
    auto it = std::find_if(pending_.begin(), pending_.end(),
                           [&](const Pending& p) { return p.command == ack.command; });
    if (it == pending_.end()) {  // a second answer (PX4 v1.16's DO_SET_MODE): the last counts
      label = late_ack(ack.command, ack.result);
      quiet = label.empty();
      result = "late";
    }
    if (result.empty() && ack.result == MAV_RESULT_IN_PROGRESS) {  // the final word: no resend
      it->deadline = now() + duration(ack_timeout_);
      it->resend = false;
      return;
    }
    if (result.empty()) {
      result = result_name(ack.result);
      label = it->label;
      quiet = it->quiet;
      answered_[it->command] = Answered{it->name, it->label, quiet, now() + duration(ack_timeout_)};
      if (!quiet) acks_[it->name] = result;
      pending_.erase(it);
    }
  }
  if (result == "late") {
    if (!quiet) say(label);
    return;
  }
  if (quiet && result == "accepted") return;
  say(label + " " + (result == "accepted" ? result : upper(result)));
}

/// Resend a command once halfway to its deadline; give up at the deadline.
void Mavlink::expire(Clock::time_point now) {
  uint8_t system, component;
  bool known = target(&system, &component);
  std::vector<std::string> expired;
  {
    std::lock_guard<std::mutex> lock(link_);
    for (auto it = pending_.begin(); it != pending_.end();) {
      if (now >= it->deadline) {
        if (!it->quiet) acks_[it->name] = "timeout";
        expired.push_back(it->label);
        it = pending_.erase(it);
        continue;
      }
      if (it->resend && now >= it->resend_at && known) {
        it->resend = false;
        send_command(system, component, *it, 1);
      }
      ++it;
    }
  }
  for (const std::string& label : expired) {
    say(label + ": no acknowledgement in " + fmt(ack_timeout_) + " s");
  }
}

std::string Mavlink::result_name(uint8_t result) {
  static const char* const names[] = {"accepted", "temporarily_rejected", "denied",
                                      "unsupported", "failed", "in_progress", "cancelled"};
  if (result < sizeof names / sizeof names[0]) return names[result];
  return "result_" + std::to_string(result);
}

}  // namespace hfsmc
