// hfsmc_mission_upload.cpp: missions and the geofence of the `mavlink` interface
// (docs/interfaces.md, "Missions"), compiled into the library hfsmc_mavlink: the twin of
// templates/python/hfsmc_mission_upload.py, with the same items, retries, outcomes and
// lines on stderr.
//
// The MISSION_ITEM_INT protocol: MISSION_COUNT, the vehicle asks for each item with
// MISSION_REQUEST_INT (or MISSION_REQUEST), MISSION_ACK ends the upload. What the vehicle
// does not answer within kRetryS is sent again, kRetries times, then the upload has
// failed (`timeout`). ArduPilot's item 0 is home; a heading is ArduPilot's CONDITION_YAW
// before the waypoint, PX4's waypoint param 4.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdint>
#include <mutex>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Waddress-of-packed-member"
#pragma GCC diagnostic ignored "-Wpedantic"
#include "mavlink/ardupilotmega/mavlink.h"
#pragma GCC diagnostic pop

#include "hfsmc/mavlink.hpp"

namespace hfsmc {
namespace {

constexpr double kRetryS = 2.0;  // a message the vehicle does not answer is sent again
constexpr int kRetries = 5;      // ... this many times, then the upload has failed
constexpr std::size_t kMaxPoints = 10000;
constexpr double kMaxTarget = 1e5;
constexpr double kPi = 3.14159265358979323846;
constexpr double kEarthRadius = 6378137.0;
constexpr uint8_t kMission = MAV_MISSION_TYPE_MISSION, kFence = MAV_MISSION_TYPE_FENCE;
const char* const kResults[] = {"accepted", "error", "unsupported_frame", "unsupported", "no_space",
                                "invalid", "invalid_param1", "invalid_param2", "invalid_param3",
                                "invalid_param4", "invalid_param5_x", "invalid_param6_y",
                                "invalid_param7", "invalid_sequence", "denied", "operation_cancelled"};

std::string g(double x) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", x);
  return buf;
}

const char* upload_name(uint8_t kind) { return kind == kFence ? "upload_fence" : "upload_mission"; }

/// last_ack's word for a MAV_MISSION_RESULT's name.
std::string outcome(const std::string& word) {
  if (word == "accepted" || word == "denied" || word == "unsupported") return word;
  if (word == "unsupported_frame") return "unsupported";
  if (word == "operation_cancelled") return "cancelled";
  return "failed";
}

/// Throws as hfsmc_mission.checked_location raises, with the point's place.
void check_point(const std::string& vehicle, const char* call, const char* what, std::size_t i,
                 double lat, double lon, double alt) {
  std::string why;
  if (!(lat >= -90.0 && lat <= 90.0)) why = "latitude " + g(lat) + " is out of range -90..90 (degrees)";
  else if (!(lon >= -180.0 && lon <= 180.0)) why = "longitude " + g(lon) + " is out of range -180..180 (degrees)";
  else if (!std::isfinite(alt) || std::fabs(alt) > kMaxTarget)
    why = "altitude " + g(alt) + " m is not a finite number within " + g(kMaxTarget) + " m";
  if (!why.empty())
    throw std::invalid_argument(vehicle + ": " + why + " (" + call + " " + what + " " + std::to_string(i) + ")");
}

int32_t e7(double degrees) { return static_cast<int32_t>(std::lround(degrees * 1e7)); }

std::string points_json(const std::vector<std::vector<double>>& points) {
  std::string out = "[";
  for (const auto& p : points) {
    std::string one;
    for (double x : p) one += (one.empty() ? "" : ",") + json_number(x);
    out += (out.size() > 1 ? ",[" : "[") + one + "]";
  }
  return out + "]";
}

/// A (lat, lon) inside a polygon of (lat, lon): ray casting on a local flat earth.
bool inside(double lat, double lon, const std::vector<std::pair<double, double>>& polygon) {
  bool result = false;
  const std::size_t n = polygon.size();
  const double k = kPi / 180.0 * kEarthRadius, c = std::cos(lat * kPi / 180.0);
  for (std::size_t i = 0; i < n; ++i) {
    const double an = (polygon[i].first - lat) * k, ae = (polygon[i].second - lon) * k * c;
    const auto& b = polygon[(i + 1) % n];
    const double bn = (b.first - lat) * k, be = (b.second - lon) * k * c;
    if ((ae > 0) != (be > 0) && 0 < an + (0 - ae) * (bn - an) / (be - ae)) result = !result;
  }
  return result;
}

}  // namespace

bool Mavlink::upload_mission(const std::vector<std::vector<double>>& points, const std::string& end) {
  if (end != "hold" && end != "land" && end != "rtl")
    throw std::invalid_argument(this->name() + ": upload_mission end `" + end + "` is not hold, land or rtl");
  if (points.size() > kMaxPoints)
    throw std::invalid_argument(this->name() + ": upload_mission: " + std::to_string(points.size()) +
                                " points, more than " + std::to_string(kMaxPoints));
  const bool px4 = current().autopilot == px4::kAutopilotPx4;
  Upload u;
  u.kind = kMission;
  if (!px4) {  // ArduPilot's item 0 is home (it writes its own there)
    const bool ok = !std::isnan(current().home.x());
    u.items.push_back({MAV_FRAME_GLOBAL, MAV_CMD_NAV_WAYPOINT, {0, 0, 0, 0}, ok ? e7(current().home.x()) : 0,
                       ok ? e7(current().home.y()) : 0, ok ? static_cast<float>(current().home.z()) : 0.0f});
    u.users.push_back(-1);
  }
  for (std::size_t i = 0; i < points.size(); ++i) {
    const auto& p = points[i];
    if (p.size() != 3 && p.size() != 4)
      throw std::invalid_argument(this->name() + ": upload_mission point " + std::to_string(i) +
                                  " is {lat, lon, alt} or {lat, lon, alt, heading}, not " +
                                  std::to_string(p.size()) + " numbers");
    check_point(this->name(), "upload_mission", "point", i, p[0], p[1], p[2]);
    const double h = p.size() == 4 ? p[3] : std::nan("");
    if (std::isinf(h)) throw std::invalid_argument(this->name() + ": heading " + g(h) + " is not finite (upload_mission point " + std::to_string(i) + ")");
    const double deg = std::isnan(h) ? h : std::fmod(std::fmod(h * 180.0 / kPi, 360.0) + 360.0, 360.0);
    if (!std::isnan(h) && !px4) {
      u.items.push_back({MAV_FRAME_MISSION, MAV_CMD_CONDITION_YAW, {static_cast<float>(deg), 0, 0, 0}, 0, 0, 0});
      u.users.push_back(-1);
    }
    u.items.push_back({MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, MAV_CMD_NAV_WAYPOINT,
                       {0, 0, 0, px4 ? static_cast<float>(deg) : 0.0f}, e7(p[0]), e7(p[1]),
                       static_cast<float>(p[2])});
    u.users.push_back(static_cast<int>(i));
  }
  if (end == "land" && !points.empty()) {
    u.items.push_back({MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, MAV_CMD_NAV_LAND, {0, 0, 0, NAN},
                       e7(points.back()[0]), e7(points.back()[1]), 0});
    u.users.push_back(-1);
  } else if (end == "rtl") {
    u.items.push_back({MAV_FRAME_MISSION, MAV_CMD_NAV_RETURN_TO_LAUNCH, {0, 0, 0, 0}, 0, 0, 0});
    u.users.push_back(-1);
  }
  tell("upload_mission", "[" + points_json(points) + "," + json_string(end) + "]");
  return start_upload("upload_mission", std::move(u));
}

bool Mavlink::upload_fence(const std::vector<std::vector<double>>& vertices) {
  if (vertices.size() > kMaxPoints)
    throw std::invalid_argument(this->name() + ": upload_fence: " + std::to_string(vertices.size()) +
                                " points, more than " + std::to_string(kMaxPoints));
  if (!vertices.empty() && vertices.size() < 3)
    throw std::invalid_argument(this->name() + ": upload_fence needs at least 3 vertices, not " +
                                std::to_string(vertices.size()));
  Upload u;
  u.kind = kFence;
  for (std::size_t i = 0; i < vertices.size(); ++i) {
    const auto& p = vertices[i];
    if (p.size() != 2)
      throw std::invalid_argument(this->name() + ": upload_fence vertex " + std::to_string(i) +
                                  " is {lat, lon}, not " + std::to_string(p.size()) + " numbers");
    check_point(this->name(), "upload_fence", "vertex", i, p[0], p[1], 0.0);
    u.items.push_back({MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION,
                       {static_cast<float>(vertices.size()), 0, 0, 0}, e7(p[0]), e7(p[1]), 0});
    u.polygon.emplace_back(e7(p[0]) / 1e7, e7(p[1]) / 1e7);
  }
  tell("upload_fence", "[" + points_json(vertices) + "]");
  return start_upload("upload_fence", std::move(u));
}

bool Mavlink::enable_fence(bool on) {
  tell("enable_fence", on ? "[true]" : "[false]");
  if (current().autopilot != px4::kAutopilotPx4 || !live()) {
    if (current().autopilot != px4::kAutopilotPx4 && live()) {
      std::lock_guard<std::mutex> lock(link_);
      fence_on_ = on;
    }
    return command("enable_fence", std::string("enable_fence ") + (on ? "1" : "0"),
                   MAV_CMD_DO_FENCE_ENABLE, {on ? 1.0f : 0.0f});
  }
  std::string result, line;
  {
    std::lock_guard<std::mutex> lock(link_);
    if (on) {
      const auto found = acks_.find("upload_fence");
      const bool ok = found != acks_.end() && found->second == "accepted" && !fence_.empty();
      result = ok ? "accepted" : "failed";
      fence_on_ = ok;
      line = ok ? "enable_fence: PX4's fence is on once uploaded (GF_ACTION says what a breach does): nothing sent"
                : "enable_fence FAILED: no fence uploaded to PX4";
    } else {
      result = "unsupported";
      line = "enable_fence 0 UNSUPPORTED: PX4 cannot turn its fence off; upload an empty fence (upload_fence({})) to remove it";
    }
    acks_["enable_fence"] = result;
  }
  instant().acks["enable_fence"] = "pending";
  say(line);
  return true;
}

bool Mavlink::start_upload(const char* name, Upload u) {
  instant().acks[name] = current().vehicle ? "pending" : "not_sent";
  if (!live()) return current().vehicle;
  if (!current().vehicle) {
    say(std::string(name) + ": not sent, no vehicle yet (no heartbeat)");
    std::lock_guard<std::mutex> lock(link_);
    acks_[name] = "not_sent";
    return false;
  }
  const std::size_t n = u.items.size();
  uint8_t system, component;
  if (!target(&system, &component)) return false;
  {
    std::lock_guard<std::mutex> lock(link_);
    if (uploads_.count(u.kind)) say(std::string(name) + ": a new upload replaces the one under way");
    u.sent_at = now();
    acks_[name] = "pending";
    send_upload(u, system, component);
    uploads_[u.kind] = std::move(u);
  }
  say(std::string(name) + ": " + std::to_string(n) + " items");
  return true;
}

void Mavlink::send_upload(const Upload& u, uint8_t system, uint8_t component) {  // under link_
  mavlink_message_t msg;
  if (u.last < 0) {
    mavlink_msg_mission_count_pack_status(sysid_, kGcsComponent, tx_status(), &msg, system, component,
                                          static_cast<uint16_t>(u.items.size()), u.kind);
  } else {
    const Item& it = u.items[static_cast<std::size_t>(u.last)];
    mavlink_msg_mission_item_int_pack_status(sysid_, kGcsComponent, tx_status(), &msg, system, component,
                                             static_cast<uint16_t>(u.last), it.frame, it.command, 0, 1, it.p[0],
                                             it.p[1], it.p[2], it.p[3], it.x, it.y, it.z, u.kind);
  }
  send(msg);
}

void Mavlink::on_mission_message(const mavlink_message& msg) {  // the reader thread
  std::vector<std::string> lines;
  uint8_t system, component;
  if (!target(&system, &component)) return;
  switch (msg.msgid) {
    case MAVLINK_MSG_ID_MISSION_REQUEST_INT:
    case MAVLINK_MSG_ID_MISSION_REQUEST: {
      const bool as_int = msg.msgid == MAVLINK_MSG_ID_MISSION_REQUEST_INT;
      const uint16_t seq = as_int ? mavlink_msg_mission_request_int_get_seq(&msg) : mavlink_msg_mission_request_get_seq(&msg);
      const uint8_t kind = as_int ? mavlink_msg_mission_request_int_get_mission_type(&msg)
                                  : mavlink_msg_mission_request_get_mission_type(&msg);
      std::lock_guard<std::mutex> lock(link_);
      auto it = uploads_.find(kind);
      if (it == uploads_.end() || seq >= it->second.items.size()) return;
      it->second.last = seq;
      it->second.retries = 0;
      it->second.sent_at = now();
      send_upload(it->second, system, component);
      return;
    }
    case MAVLINK_MSG_ID_MISSION_ACK: {
      const uint8_t kind = mavlink_msg_mission_ack_get_mission_type(&msg);
      const uint8_t result = mavlink_msg_mission_ack_get_type(&msg);
      bool mission = false;
      int points = 0;
      {
        std::lock_guard<std::mutex> lock(link_);
        auto it = uploads_.find(kind);
        if (it == uploads_.end()) return;
        Upload u = std::move(it->second);
        uploads_.erase(it);
        const std::string word = result < 16 ? kResults[result] : "result_" + std::to_string(result);
        const char* name = upload_name(kind);
        acks_[name] = outcome(word);
        if (word == "accepted") {
          lines.push_back(std::string(name) + " accepted (" + std::to_string(u.items.size()) + " items)");
          if (kind == kMission) {
            for (int user : u.users) points += user >= 0;
            users_ = u.users;
            mission = true;
          } else {
            fence_ = u.polygon;
          }
        } else {
          lines.push_back(std::string(name) + " " + upper(word) +
                          (u.last >= 0 ? " (at item " + std::to_string(u.last) + ")" : ""));
        }
      }
      if (mission) {
        std::lock_guard<std::mutex> lock(state_);
        s_.mission_current = 0;
        s_.mission_total = points;
      }
      break;
    }
    case MAVLINK_MSG_ID_MISSION_CURRENT:
    case MAVLINK_MSG_ID_MISSION_ITEM_REACHED: {
      const bool current = msg.msgid == MAVLINK_MSG_ID_MISSION_CURRENT;
      const int seq = current ? mavlink_msg_mission_current_get_seq(&msg) : mavlink_msg_mission_item_reached_get_seq(&msg);
      int at = -1, total = -1;
      bool reached = false;
      {
        std::lock_guard<std::mutex> lock(link_);
        if (users_.empty()) {  // a mission this driver did not upload: the vehicle's numbering
          if (!current) return;
          const int offset = px4() ? 0 : 1;
          at = std::max(0, seq - offset);
          total = std::max(0, static_cast<int>(mavlink_msg_mission_current_get_total(&msg)) - offset);
        } else {
          int points = 0;
          for (int u : users_) points += u >= 0;
          total = points;
          if (!current) {
            if (seq < 0 || static_cast<std::size_t>(seq) >= users_.size() || users_[seq] < 0) return;
            at = users_[seq] + 1;
            reached = true;
          } else if (mavlink_msg_mission_current_get_mission_state(&msg) == MISSION_STATE_COMPLETE) {
            at = points;
          } else {
            at = points;
            for (std::size_t i = static_cast<std::size_t>(std::max(0, seq)); i < users_.size(); ++i)
              if (users_[i] >= 0) { at = users_[i]; break; }
          }
        }
      }
      std::lock_guard<std::mutex> lock(state_);
      s_.mission_current = reached ? std::max(s_.mission_current, at) : at;
      s_.mission_total = total;
      return;
    }
    case MAVLINK_MSG_ID_FENCE_STATUS: {
      const bool breached = mavlink_msg_fence_status_get_breach_status(&msg) != 0;
      bool was;
      {
        std::lock_guard<std::mutex> lock(state_);
        was = s_.fence_breached;
        s_.fence_breached = breached;
      }
      if (breached && !was) lines.push_back("fence breached");
      break;
    }
    default:
      return;
  }
  for (const std::string& line : lines) say(line);
}

void Mavlink::upload_tick(Clock::time_point t) {
  std::vector<std::string> lines;
  uint8_t system, component;
  if (!target(&system, &component)) return;
  {
    std::lock_guard<std::mutex> lock(link_);
    for (auto it = uploads_.begin(); it != uploads_.end();) {
      Upload& u = it->second;
      if (seconds(t - u.sent_at) < kRetryS) {
        ++it;
        continue;
      }
      if (u.retries >= kRetries) {
        acks_[upload_name(u.kind)] = "timeout";
        lines.push_back(std::string(upload_name(u.kind)) + ": no answer after " + std::to_string(kRetries) + " resends");
        it = uploads_.erase(it);
        continue;
      }
      ++u.retries;
      u.sent_at = t;
      send_upload(u, system, component);
      ++it;
    }
  }
  for (const std::string& line : lines) say(line);
}

void Mavlink::fence_check(double lat, double lon) {
  bool outside;
  {
    std::lock_guard<std::mutex> lock(link_);
    outside = fence_.size() >= 3 && (fence_on_ || px4()) && !inside(lat, lon, fence_);
  }
  if (!outside) return;
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.7f, %.7f", lat, lon);
  say(std::string("goto_location ") + buf + " is outside the fence: " +
      (px4() ? "PX4 will fly it and breach the fence" : "ArduPilot ignores it (the vehicle keeps its previous target)"));
}

}  // namespace hfsmc
