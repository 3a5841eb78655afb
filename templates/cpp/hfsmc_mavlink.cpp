// hfsmc_mavlink.cpp: the `mavlink` interface of C++ components (hfsmc/mavlink.hpp
// declares it and says how it works), compiled once into the library hfsmc_mavlink
// with mavgen's C headers. Copied unchanged into every component folder that uses it.
//
// This file: what the vehicle says (its telemetry, under state_) and what the automaton
// sees of it (the snapshot the base takes, the vehicle panel of the live views, the
// warning at stop); hfsmc_mavlink_link.cpp opens the link and runs the reader,
// hfsmc_mavlink_commands.cpp sends the commands and follows their acks.
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

/// What warning_at_stop() says (the base keeps a replay from noting these queries): the
/// vehicle still armed as the component stops (then nothing lands it: --until, an error
/// without on_interrupt...); "" when disarmed.
std::string Mavlink::stop_warning() const {
  if (!armed()) return "";
  char alt[64];
  std::snprintf(alt, sizeof alt, "%.1f", altitude());
  std::string link;
  if (!connected()) {
    char age[64];
    std::snprintf(age, sizeof age, "%.0f", heartbeat_age());
    link = std::string(" (link lost ") + age + " s ago)";
  }
  return "WARNING: ARMED in " + mode() + " at " + alt + " m" + link +
         " as the component stops: nothing lands the vehicle now";
}

/// The last outcome of a command (arm, disarm, takeoff, land, rtl, set_mode):
/// accepted, denied, temporarily_rejected, unsupported, failed, cancelled,
/// pending, timeout, not_sent; "" when never sent.
std::string Mavlink::last_ack(const std::string& command) const {
  const Snap& s = snap("last_ack", "acks");
  auto it = s.acks.find(command);
  return it == s.acks.end() ? std::string() : it->second;
}

/// A `vehicle` message (schemas/monitor.md) from the state at hand: no request is sent.
std::string Mavlink::feed_message(long long t_ms) {
  const Snap now = live_snapshot();  // the monitor's thread: never the automaton's snapshot
  auto num = [](double x, const char* format) {
    if (!std::isfinite(x)) return std::string("null");
    char b[64];
    std::snprintf(b, sizeof b, format, x);
    return std::string(b);
  };
  auto triple = [&num](const Eigen::Vector3d& v) {
    if (!std::isfinite(v.x()) && !std::isfinite(v.y()) && !std::isfinite(v.z()))
      return std::string("null");
    return "[" + num(v.x(), "%.3f") + "," + num(v.y(), "%.3f") + "," + num(v.z(), "%.3f") + "]";
  };
  const long long percent = now.battery;
  return "{\"type\":\"vehicle\",\"t\":" + std::to_string(t_ms) + ",\"name\":" + json_string(this->name()) +
         ",\"connected\":" + (now.heartbeat_age < kLinkTimeoutS ? "true" : "false") +
         ",\"mode\":" + json_string(now.mode) + ",\"armed\":" + (now.armed ? "true" : "false") +
         ",\"altitude\":" + num(now.altitude, "%.3f") + ",\"position\":" + triple(now.position) +
         ",\"velocity\":" + triple(now.velocity) +
         ",\"battery\":" + (percent >= 0 ? std::to_string(percent) : std::string("null")) +
         ",\"link_age\":" + num(now.heartbeat_age, "%.2f") + "}";
}

/// The state at hand, as a snapshot (any thread).
Mavlink::Snap Mavlink::live_snapshot() const {
  Snap n;
  uint16_t flags;
  int fix;
  bool prearm;
  {
    std::lock_guard<std::mutex> lock(state_);
    n.heartbeat_age = s_.heartbeat_seen ? seconds(now() - s_.heartbeat_at) : kInf;
    n.armed = s_.base_mode & MAV_MODE_FLAG_SAFETY_ARMED;
    n.mode = s_.heartbeat_seen ? mode_name(s_.type, s_.custom_mode) : std::string();
    n.position = s_.position;
    n.altitude = s_.relative_alt_seen ? s_.relative_alt : -s_.position.z();
    n.velocity = s_.velocity;
    n.yaw = s_.yaw;
    n.battery = s_.battery;
    n.vehicle = s_.target_seen;
    n.type = s_.type;
    n.autopilot = px4() ? px4::kAutopilotPx4 : s_.autopilot;
    if (px4() && s_.heartbeat_seen) n.mode = px4::mode_name(s_.custom_mode);
    n.location = s_.location;
    n.home = s_.home;
    n.status_text = s_.status_text;
    n.battery_failsafe = s_.battery_failsafe;
    n.mission[0] = s_.mission_current;
    n.mission[1] = s_.mission_total;
    n.fence_breached = s_.fence_breached;
    flags = s_.ekf_flags;
    fix = s_.gps_fix;
    prearm = s_.prearm;
  }
  bool position = px4() ? prearm
                  : n.armed ? (flags & EKF_POS_HORIZ_ABS) && !(flags & EKF_CONST_POS_MODE)
                            : (flags & (EKF_POS_HORIZ_ABS | EKF_PRED_POS_HORIZ_ABS));
  n.ready = n.heartbeat_age < kLinkTimeoutS && fix >= GPS_FIX_TYPE_3D_FIX && position;
  n.failsafe = std::isfinite(n.heartbeat_age) && n.heartbeat_age >= kLinkTimeoutS ? "link_lost"
               : offboard_ && offboard_->lost()                                   ? "offboard_lost"
               : n.fence_breached                                                  ? "fence"
               : !n.battery_failsafe.empty()                                       ? "battery"
                                                                                   : "";
  std::lock_guard<std::mutex> lock(link_);
  n.acks = acks_;
  return n;
}

void Mavlink::handle(const mavlink_message_t& msg) {
  if (duplicate(msg)) return;
  if (msg.msgid == MAVLINK_MSG_ID_HEARTBEAT) {
    on_heartbeat(msg);
    return;
  }
  if (msg.msgid == MAVLINK_MSG_ID_COMMAND_ACK) {
    uint8_t system, component;
    if (target(&system, &component) && msg.sysid == system) on_ack(msg);
    return;
  }
  if (msg.msgid == MAVLINK_MSG_ID_STATUSTEXT) {
    uint8_t system, component;
    if (target(&system, &component) && msg.sysid == system) on_statustext(msg);
    return;
  }
  switch (msg.msgid) {
    case MAVLINK_MSG_ID_MISSION_REQUEST_INT: case MAVLINK_MSG_ID_MISSION_REQUEST:
    case MAVLINK_MSG_ID_MISSION_ACK: case MAVLINK_MSG_ID_MISSION_CURRENT:
    case MAVLINK_MSG_ID_MISSION_ITEM_REACHED: case MAVLINK_MSG_ID_FENCE_STATUS: {
      uint8_t system, component;
      if (target(&system, &component) && msg.sysid == system) on_mission_message(msg);
      return;
    }
    default:
      break;
  }
  std::lock_guard<std::mutex> lock(state_);
  if (!s_.target_seen || msg.sysid != s_.target_system) return;
  switch (msg.msgid) {
    case MAVLINK_MSG_ID_LOCAL_POSITION_NED: {
      mavlink_local_position_ned_t m;
      mavlink_msg_local_position_ned_decode(&msg, &m);
      s_.position = Eigen::Vector3d(m.x, m.y, m.z);
      s_.velocity = Eigen::Vector3d(m.vx, m.vy, m.vz);
      break;
    }
    case MAVLINK_MSG_ID_GLOBAL_POSITION_INT: {
      mavlink_global_position_int_t m;
      mavlink_msg_global_position_int_decode(&msg, &m);
      s_.relative_alt = m.relative_alt / 1000.0;
      s_.relative_alt_seen = true;
      s_.location = m.lat != 0 || m.lon != 0
                        ? Eigen::Vector3d(m.lat / 1e7, m.lon / 1e7, m.relative_alt / 1000.0)
                        : Eigen::Vector3d(kNaN, kNaN, kNaN);
      if (m.lat != 0 || m.lon != 0) {
        s_.home_amsl = (static_cast<int64_t>(m.alt) - m.relative_alt) / 1000.0;
        s_.home_amsl_seen = true;
      }
      break;
    }
    case MAVLINK_MSG_ID_ATTITUDE:
      s_.yaw = mavlink_msg_attitude_get_yaw(&msg);
      break;
    case MAVLINK_MSG_ID_SYS_STATUS:
      s_.battery = mavlink_msg_sys_status_get_battery_remaining(&msg);
      s_.prearm = mavlink_msg_sys_status_get_onboard_control_sensors_health(&msg) &
                  MAV_SYS_STATUS_PREARM_CHECK;
      break;
    case MAVLINK_MSG_ID_GPS_RAW_INT:
      s_.gps_fix = mavlink_msg_gps_raw_int_get_fix_type(&msg);
      break;
    case MAVLINK_MSG_ID_HOME_POSITION:
      on_home(msg);
      break;
    case MAVLINK_MSG_ID_BATTERY_STATUS:
      on_battery_status(msg);
      break;
    case MAVLINK_MSG_ID_EKF_STATUS_REPORT:
      s_.ekf_flags = mavlink_msg_ekf_status_report_get_flags(&msg);
      break;
    default:
      break;
  }
}

void Mavlink::on_heartbeat(const mavlink_message_t& msg) {
  mavlink_heartbeat_t hb;
  mavlink_msg_heartbeat_decode(&msg, &hb);
  if (hb.autopilot == MAV_AUTOPILOT_INVALID || hb.type == MAV_TYPE_GCS) {
    return;  // a ground station, a camera, a gimbal: not the vehicle
  }
  bool first, back = false;
  std::string now_mode;
  {
    std::lock_guard<std::mutex> lock(state_);
    if (s_.target_seen &&
        (msg.sysid != s_.target_system || msg.compid != s_.target_component)) {
      return;
    }
    first = !s_.target_seen;
    if (first && autopilot_ == "auto") px4_ = hb.autopilot == px4::kAutopilotPx4;
    s_.target_seen = true;
    s_.target_system = msg.sysid;
    s_.target_component = msg.compid;
    s_.type = hb.type;
    s_.autopilot = hb.autopilot;
    s_.base_mode = hb.base_mode;
    s_.custom_mode = hb.custom_mode;
    s_.heartbeat_seen = true;
    s_.heartbeat_at = now();
    now_mode = px4() ? px4::mode_name(s_.custom_mode) : mode_name(s_.type, s_.custom_mode);
  }
  if (first) {
    say(std::string(px4() ? "PX4 " : "") + "vehicle " + std::to_string(msg.sysid) + "/" + std::to_string(msg.compid) + " on " +
        url() + ", mode " + now_mode);
    request_rates();
  } else if (lost_) {
    lost_ = false;
    back = true;
  }
  if (back) {
    say("link back");
    request_rates();  // the vehicle may have restarted
  }
}

// -- helpers -----------------------------------------------------------------------
Mavlink::ModeTable Mavlink::modes(uint8_t type) {
  // pymavlink's mode_mapping_bynumber (ArduPilot's numbers), Copter's by default.
  static const Mode copter[] = {
      {0, "STABILIZE"}, {1, "ACRO"},       {2, "ALT_HOLD"},   {3, "AUTO"},
      {4, "GUIDED"},    {5, "LOITER"},     {6, "RTL"},        {7, "CIRCLE"},
      {8, "POSITION"},  {9, "LAND"},       {10, "OF_LOITER"}, {11, "DRIFT"},
      {13, "SPORT"},    {14, "FLIP"},      {15, "AUTOTUNE"},  {16, "POSHOLD"},
      {17, "BRAKE"},    {18, "THROW"},     {19, "AVOID_ADSB"}, {20, "GUIDED_NOGPS"},
      {21, "SMART_RTL"}, {22, "FLOWHOLD"}, {23, "FOLLOW"},    {24, "ZIGZAG"},
      {25, "SYSTEMID"}, {26, "AUTOROTATE"}, {27, "AUTO_RTL"}, {28, "TURTLE"},
      {29, "RATE_ACRO"}};
  static const Mode plane[] = {
      {0, "MANUAL"},  {1, "CIRCLE"},      {2, "STABILIZE"},   {3, "TRAINING"},
      {4, "ACRO"},    {5, "FBWA"},        {6, "FBWB"},        {7, "CRUISE"},
      {8, "AUTOTUNE"}, {10, "AUTO"},      {11, "RTL"},        {12, "LOITER"},
      {13, "TAKEOFF"}, {14, "AVOID_ADSB"}, {15, "GUIDED"},    {16, "INITIALISING"},
      {17, "QSTABILIZE"}, {18, "QHOVER"}, {19, "QLOITER"},    {20, "QLAND"},
      {21, "QRTL"},   {22, "QAUTOTUNE"},  {23, "QACRO"},      {24, "THERMAL"},
      {25, "LOITERALTQLAND"}, {26, "AUTOLAND"}};
  static const Mode rover[] = {
      {0, "MANUAL"}, {1, "ACRO"},  {2, "LEARNING"}, {3, "STEERING"}, {4, "HOLD"},
      {5, "LOITER"}, {6, "FOLLOW"}, {7, "SIMPLE"},  {8, "DOCK"},     {9, "CIRCLE"},
      {10, "AUTO"},  {11, "RTL"},  {12, "SMART_RTL"}, {15, "GUIDED"}, {16, "INITIALISING"}};
  static const Mode tracker[] = {{0, "MANUAL"}, {1, "STOP"}, {2, "SCAN"},
                                 {4, "GUIDED"}, {10, "AUTO"}, {16, "INITIALISING"}};
  static const Mode sub[] = {{0, "STABILIZE"}, {1, "ACRO"},    {2, "ALT_HOLD"},
                             {3, "AUTO"},      {4, "GUIDED"},  {7, "CIRCLE"},
                             {9, "SURFACE"},   {16, "POSHOLD"}, {19, "MANUAL"}};
  static const Mode blimp[] = {{0, "LAND"}, {1, "MANUAL"}, {2, "VELOCITY"}, {3, "LOITER"},
                               {4, "RTL"},  {5, "AUTO"},   {6, "HOLD"}};
  switch (type) {
    case MAV_TYPE_FIXED_WING:
    case MAV_TYPE_VTOL_DUOROTOR:
    case MAV_TYPE_VTOL_QUADROTOR:
    case MAV_TYPE_VTOL_TILTROTOR:
      return {std::begin(plane), std::end(plane)};
    case MAV_TYPE_GROUND_ROVER:
    case MAV_TYPE_SURFACE_BOAT:
      return {std::begin(rover), std::end(rover)};
    case MAV_TYPE_ANTENNA_TRACKER:
      return {std::begin(tracker), std::end(tracker)};
    case MAV_TYPE_SUBMARINE:
      return {std::begin(sub), std::end(sub)};
    case MAV_TYPE_AIRSHIP:
      return {std::begin(blimp), std::end(blimp)};
    default:
      return {std::begin(copter), std::end(copter)};
  }
}

std::string Mavlink::mode_name(uint8_t type, uint32_t custom) {
  ModeTable table = modes(type);
  for (const Mode* m = table.first; m != table.second; ++m) {
    if (m->number == custom) return m->name;
  }
  return "MODE" + std::to_string(custom);
}

std::string Mavlink::strip(const std::string& s) {
  const char* space = " \t\n\r\f\v";
  size_t a = s.find_first_not_of(space);
  if (a == std::string::npos) return "";
  return s.substr(a, s.find_last_not_of(space) - a + 1);
}

std::string Mavlink::upper(std::string s) {
  for (char& c : s) {
    if (c >= 'a' && c <= 'z') c = static_cast<char>(c - 'a' + 'A');
  }
  return s;
}

std::string Mavlink::fmt(double x) {  // Python's `{x:g}`
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", x);
  return buf;
}

}  // namespace hfsmc
