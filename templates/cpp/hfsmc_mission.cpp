// hfsmc_mission.cpp: the mission API of the `mavlink` interface (docs/interfaces.md,
// "Missions"), compiled into the library hfsmc_mavlink beside hfsmc_mavlink.cpp: the twin
// of templates/python/hfsmc_mission.py and of VehicleQueries' mission methods, with the
// same checks, the same messages and the same datagrams.
//
// Latitudes and longitudes in degrees, checked before anything is sent; distances on a
// local flat earth around the points; targets by latitude and longitude in
// MAV_FRAME_GLOBAL_RELATIVE_ALT_INT (altitude above home); headings in rad, NaN for none.
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <mutex>
#include <stdexcept>
#include <string>

#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Waddress-of-packed-member"
#pragma GCC diagnostic ignored "-Wpedantic"
#include "mavlink/ardupilotmega/mavlink.h"
#pragma GCC diagnostic pop

#include "hfsmc/mavlink.hpp"

namespace hfsmc {
namespace {

constexpr double kEarthRadius = 6378137.0;  // m, WGS84's equatorial radius
constexpr double kMaxTarget = 1e5;  // m: a target further than this is refused
constexpr double kPi = 3.14159265358979323846;
constexpr uint16_t kIgnoreVelocityAcceleration = 0b0001'1111'1000;
constexpr uint16_t kIgnoreYaw = 0b0100'0000'0000;
constexpr uint16_t kIgnoreYawRate = 0b1000'0000'0000;

double radians(double degrees) { return degrees * kPi / 180.0; }

std::string g(double x) {  // Python's `{x:g}`
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", x);
  return buf;
}

/// Throws std::invalid_argument as hfsmc_mission.checked_location raises ValueError.
void check_location(const std::string& vehicle, double lat, double lon, double alt) {
  if (!(lat >= -90.0 && lat <= 90.0))
    throw std::invalid_argument(vehicle + ": latitude " + g(lat) + " is out of range -90..90 (degrees)");
  if (!(lon >= -180.0 && lon <= 180.0))
    throw std::invalid_argument(vehicle + ": longitude " + g(lon) + " is out of range -180..180 (degrees)");
  if (!std::isfinite(alt) || std::fabs(alt) > kMaxTarget)
    throw std::invalid_argument(vehicle + ": altitude " + g(alt) + " m is not a finite number within " +
                                g(kMaxTarget) + " m");
}

void check_heading(const std::string& vehicle, double heading) {
  if (std::isinf(heading)) throw std::invalid_argument(vehicle + ": heading " + g(heading) + " is not finite");
}

/// m between (lat, lon, alt) and a point; horizontal when `alt` is NaN.
double distance(const Eigen::Vector3d& here, double lat, double lon, double alt) {
  const double north = radians(lat - here.x()) * kEarthRadius;
  double dlon = std::fmod(lon - here.y() + 180.0, 360.0);
  if (dlon < 0) dlon += 360.0;  // Python's % (the sign of the divisor)
  dlon -= 180.0;
  const double east = radians(dlon) * kEarthRadius * std::cos(radians((here.x() + lat) / 2));
  if (std::isnan(alt)) return std::hypot(north, east);
  const double up = alt - here.z();
  return std::sqrt(north * north + east * east + up * up);
}

}  // namespace

double Mavlink::distance_to(double north, double east, double alt) const {
  snap("distance_to", "position");
  const double dn = north - current().position.x(), de = east - current().position.y();
  if (std::isnan(alt)) return std::hypot(dn, de);
  const double up = alt - current().altitude;
  return std::sqrt(dn * dn + de * de + up * up);
}

double Mavlink::distance_to_location(double lat, double lon, double alt) const {
  snap("distance_to_location", "location");
  check_location(this->name(), lat, lon, std::isnan(alt) ? 0.0 : alt);
  return distance(current().location, lat, lon, alt);
}

bool Mavlink::reached(double north, double east, double alt, double tolerance) const {
  return distance_to(north, east, alt) <= tolerance;
}

bool Mavlink::reached_location(double lat, double lon, double alt, double tolerance) const {
  return distance_to_location(lat, lon, alt) <= tolerance;
}

bool Mavlink::go_to(double north, double east, double alt, double heading) {
  check_heading(this->name(), heading);
  std::string args = json_number(north) + "," + json_number(east) + "," + json_number(alt);
  if (!std::isnan(heading)) args += "," + json_number(heading);
  tell("goto", "[" + args + "]");
  aim_ = Aim{1, north, east, alt};
  return go_local(north, east, alt, heading);
}

bool Mavlink::goto_location(double lat, double lon, double alt, double heading) {
  check_location(this->name(), lat, lon, alt);
  check_heading(this->name(), heading);
  std::string args = json_number(lat) + "," + json_number(lon) + "," + json_number(alt);
  if (!std::isnan(heading)) args += "," + json_number(heading);
  tell("goto_location", "[" + args + "]");
  aim_ = Aim{2, lat, lon, alt};
  return go_global(lat, lon, alt, heading);
}

bool Mavlink::set_yaw(double heading) {
  check_heading(this->name(), heading);
  if (std::isnan(heading))
    throw std::invalid_argument(this->name() + ": set_yaw needs a heading in rad, not " + g(heading));
  tell("set_yaw", "[" + json_number(heading) + "]");
  if (aim_.kind == 1) return go_local(aim_.a, aim_.b, aim_.alt, heading);
  if (aim_.kind == 2) return go_global(aim_.a, aim_.b, aim_.alt, heading);
  return target_local(MAV_FRAME_LOCAL_NED, kStopFacingMask, {0, 0, 0}, {0, 0, 0}, 0, heading);
}

bool Mavlink::rtl(double alt) {
  if (std::isnan(alt)) {
    tell("rtl", "[]");
  } else {
    if (!(alt > 0.0 && alt <= kMaxTarget))
      throw std::invalid_argument(this->name() + ": rtl altitude " + g(alt) + " m is not above home");
    tell("rtl", "[" + json_number(alt) + "]");
    if (live() && current().vehicle) send_rtl_altitude(alt);
  }
  return command("rtl", "rtl", MAV_CMD_NAV_RETURN_TO_LAUNCH, {});
}

bool Mavlink::go_local(double north, double east, double alt, double heading) {
  const bool facing = !std::isnan(heading);
  const uint16_t mask = facing ? kPositionMask & ~kIgnoreYaw : kPositionMask;
  return target_local(MAV_FRAME_LOCAL_NED, mask, {north, east, -alt}, {0, 0, 0}, 0,
                      facing ? heading : 0.0);
}

bool Mavlink::go_global(double lat, double lon, double alt, double heading) {
  if (!current().vehicle) return false;  // a stream of targets: nothing to say
  uint8_t system, component;
  if (!live() || !target(&system, &component)) return true;
  fence_check(lat, lon);
  const bool facing = !std::isnan(heading);
  px4::Target t;
  t.global = true;
  t.frame = MAV_FRAME_GLOBAL_RELATIVE_ALT_INT;
  t.mask = kIgnoreVelocityAcceleration | kIgnoreYawRate | (facing ? 0 : kIgnoreYaw);
  t.pos[0] = lat;
  t.pos[1] = lon;
  t.pos[2] = alt;
  t.yaw = facing ? heading : 0.0;
  send_target(t);
  if (px4()) offboard_->target(now_s(), t);
  return true;
}

void Mavlink::on_home(const mavlink_message& msg) {  // under state_
  mavlink_home_position_t m;
  mavlink_msg_home_position_decode(&msg, &m);
  s_.home = Eigen::Vector3d(m.latitude / 1e7, m.longitude / 1e7, m.altitude / 1000.0);
}

void Mavlink::on_battery_status(const mavlink_message& msg) {  // under state_
  switch (mavlink_msg_battery_status_get_charge_state(&msg)) {
    case MAV_BATTERY_CHARGE_STATE_LOW: s_.battery_failsafe = "low"; break;
    case MAV_BATTERY_CHARGE_STATE_CRITICAL: s_.battery_failsafe = "critical"; break;
    case MAV_BATTERY_CHARGE_STATE_EMERGENCY: s_.battery_failsafe = "emergency"; break;
    case MAV_BATTERY_CHARGE_STATE_FAILED: s_.battery_failsafe = "failed"; break;
    case MAV_BATTERY_CHARGE_STATE_UNHEALTHY: s_.battery_failsafe = "unhealthy"; break;
    default: s_.battery_failsafe.clear(); break;
  }
}

}  // namespace hfsmc
