// hfsmc_mavlink.cpp: the `mavlink` interface of C++ components (hfsmc/mavlink.hpp
// declares it and says how it works), compiled once into the library hfsmc_mavlink
// with mavgen's C headers. Copied unchanged into every component folder that uses it.
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

struct Mavlink::Wire {  // under link_
  sockaddr_in peer{};
  mavlink_message_t rx_msg{};
  mavlink_status_t rx_status{};
  mavlink_status_t tx_status{};
};

Mavlink::Mavlink(const std::string& name, const std::string& url,
                 const std::map<std::string, std::string>& options)
    : name_(name), url_(url.empty() ? kDefaultUrl : url), options_(options), sim_(simclock::current()), start_(now()),
      wire_(std::make_unique<Wire>()) {
  rate_ = option(options, "rate", kFastRateHz);
  ack_timeout_ = option(options, "ack_timeout", kAckTimeoutS);
  double sysid = std::trunc(option(options, "source_system", 255.0));
  if (sysid < 1 || sysid > 255) {
    say("option source_system: " + fmt(sysid) + " is not 1..255, 255 used");
    sysid = 255;
  }
  sysid_ = static_cast<uint8_t>(sysid);
  auto chosen = options.find("autopilot");
  if (chosen != options.end()) {
    autopilot_ = chosen->second;
    for (char& c : autopilot_) c = static_cast<char>(c >= 'A' && c <= 'Z' ? c - 'A' + 'a' : c);
    if (autopilot_ != "auto" && autopilot_ != "ardupilot" && autopilot_ != "px4") {
      say("option autopilot: `" + autopilot_ + "` is not auto, ardupilot or px4; auto used");
      autopilot_ = "auto";
    }
  }
  px4_ = autopilot_ == "px4";  // else known from the first heartbeat
  for (const auto& kv : options) {
    if (kv.first != "rate" && kv.first != "ack_timeout" && kv.first != "source_system" &&
        kv.first != "autopilot") {
      say("unknown option `" + kv.first +
          "` ignored (options: rate, ack_timeout, source_system, autopilot)");
    }
  }
  offboard_ = std::make_unique<px4::Offboard>(
      [this](const px4::Target& t) { send_target(t); },
      [this] {
        Pending p{"set_mode", "set_mode GUIDED (OFFBOARD)", MAV_CMD_DO_SET_MODE, {0, 0, 0, 0, 0, 0, 0},
                  {}, {}, true, false};
        px4::set_mode_params(px4::kOffboard, &p.params[0], &p.params[1], &p.params[2]);
        send_long(p);
      },
      [this](const std::string& line) { say(line); });
  if (playback::Inputs* inputs = playback::current()) {  // a fake fed from the inputs
    inputs_ = inputs;
    Snap scratch;  // every entry checked now: a bad value is said before the run
    for (const playback::Entry& e : inputs->entries(name_)) apply(scratch, e);
    register_source(this);
    return;
  }
  std::string why = open_socket();
  if (!why.empty()) {
    say("cannot open " + url_ + ": " + why);
    std::exit(1);
  }
  if (simclock::Client* sim = simclock::current()) {  // lockstep: no reader thread
    sim_ = sim;
    sim->add(this);
  } else {
    reader_ = quiet_thread([this] { run(); });
  }
  register_feed(this);
  register_source(this);
}

Mavlink::Clock::time_point Mavlink::now() const {
  if (sim_ == nullptr) return Clock::now();
  return Clock::time_point(std::chrono::duration_cast<Clock::duration>(
      std::chrono::microseconds(sim_->now_us())));
}

/// Lockstep, before the instant at t_us: read until the simulator's `sent` datagrams
/// have come, then do the reader's timed work; why not, or "".
std::string Mavlink::lockstep_sync(long long, const simclock::Step& step) {
  const auto end = Clock::now() + duration(kDatagramWaitS);
  for (;;) {
    drain();
    if (received_ >= step.sent) break;
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(end - Clock::now()).count();
    if (left <= 0)
      return name_ + ": " + std::to_string(step.sent - received_) +
             " of the simulator's datagrams did not come in " + fmt(kDatagramWaitS) + " s (is " + url_ +
             " the simulator's link?)";
    pollfd pfd{fd_, POLLIN, 0};
    ::poll(&pfd, 1, static_cast<int>(std::min<long long>(left, kPollMs)));
  }
  timed(now());
  return "";
}

Mavlink::~Mavlink() {
  if (sim_ != nullptr && simclock::current() == sim_) sim_->remove(this);
  unregister_source(this);
  unregister_feed(this);
  close();
}

/// What the component says when it stops with the vehicle still armed (then nothing
/// lands it: --until, an error without on_interrupt...); "" when disarmed.
std::string Mavlink::warning_at_stop() const {
  evidence_.quiet(true);  // the runtime reads the last snapshot: no snippet asks
  struct Loud {
    const playback::Evidence& e;
    ~Loud() { e.quiet(false); }
  } loud{evidence_};
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
  evidence_.asked("last_ack", "acks");
  auto it = snap_.acks.find(command);
  return it == snap_.acks.end() ? std::string() : it->second;
}

std::string Mavlink::source_config() const {
  std::string options;
  for (const auto& kv : options_)
    options += (options.empty() ? "" : ",") + json_string(kv.first) + ":" + json_string(kv.second);
  return "{\"type\":\"mavlink\",\"url\":" + json_string(url_) + ",\"options\":{" + options + "}}";
}

void Mavlink::take_snapshot(long long t_us) {
  snapshot_t_ = t_us;
  if (inputs_ == nullptr) {
    snap_ = live_snapshot();
    return;
  }
  const std::vector<playback::Entry>& entries = inputs_->entries(name_);
  for (; next_ < entries.size() && entries[next_].t <= t_us; ++next_) apply(fed_, entries[next_]);
  snap_ = fed_;
  evidence_.at(inputs_, name_, t_us, next_ > 0 ? &entries[next_ - 1] : nullptr, -1);
}

std::string Mavlink::snapshot_fields() const {
  const auto triple = [](const Eigen::Vector3d& v) {
    return "[" + json_number(v.x()) + "," + json_number(v.y()) + "," + json_number(v.z()) + "]";
  };
  std::string acks;
  for (const auto& kv : snap_.acks)
    acks += (acks.empty() ? "" : ",") + json_string(kv.first) + ":" + json_string(kv.second);
  return "\"heartbeat_age\":" + json_number(snap_.heartbeat_age) +
         ",\"ready\":" + (snap_.ready ? "true" : "false") + ",\"armed\":" + (snap_.armed ? "true" : "false") +
         ",\"mode\":" + json_string(snap_.mode) + ",\"position\":" + triple(snap_.position) +
         ",\"altitude\":" + json_number(snap_.altitude) + ",\"velocity\":" + triple(snap_.velocity) +
         ",\"yaw\":" + json_number(snap_.yaw) + ",\"battery\":" + std::to_string(snap_.battery) +
         ",\"acks\":{" + acks + "},\"vehicle\":" + (snap_.vehicle ? "true" : "false") +
         ",\"type\":" + std::to_string(snap_.type) + ",\"autopilot\":" + std::to_string(snap_.autopilot) +
         ",\"location\":" + triple(snap_.location) + ",\"home\":" + triple(snap_.home) +
         ",\"status_text\":" + json_string(snap_.status_text) +
         ",\"battery_failsafe\":" + json_string(snap_.battery_failsafe) +
         ",\"mission\":[" + std::to_string(snap_.mission.first) + "," + std::to_string(snap_.mission.second) +
         "],\"fence_breached\":" + (snap_.fence_breached ? "true" : "false") +
         ",\"failsafe\":" + json_string(snap_.failsafe);
}

// -- commands (send and return; true when sent, i.e. a vehicle is known) ---------
/// Ask for a flight mode by name (MAV_CMD_DO_SET_MODE with the custom mode).
/// An unknown name throws std::invalid_argument (Python: ValueError).
bool Mavlink::set_mode(const std::string& name) {
  std::string wanted = upper(strip(name));
  if (snap_.autopilot == px4::kAutopilotPx4) {  // PX4's names: px4.hpp
    uint32_t number = 0;
    if (!px4::mode_number(name, &number))
      throw std::invalid_argument(name_ + ": PX4 has no mode `" + name + "` (modes: " + px4::mode_list() + ")");
    sent("set_mode", "[" + json_string(name) + "]");
    if (inputs_ != nullptr) return command("set_mode", "set_mode " + wanted, MAV_CMD_DO_SET_MODE, {});
    return px4_mode(wanted, number);
  }
  const ModeTable table = modes(static_cast<uint8_t>(snap_.type));
  const Mode* found = nullptr;
  std::string names;
  for (const Mode* m = table.first; m != table.second; ++m) {
    if (wanted == m->name) found = m;
    names += (names.empty() ? "" : ", ") + std::string(m->name);
  }
  if (found == nullptr) {
    throw std::invalid_argument(name_ + ": unknown mode `" + name + "` (modes: " + names + ")");
  }
  sent("set_mode", "[" + json_string(name) + "]");
  return command("set_mode", "set_mode " + wanted, MAV_CMD_DO_SET_MODE,
                 {MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, static_cast<float>(found->number)});
}

/// Arm the motors (MAV_CMD_COMPONENT_ARM_DISARM 1).
bool Mavlink::arm() {
  sent("arm", "[]");
  return command("arm", "arm", MAV_CMD_COMPONENT_ARM_DISARM, {1});
}

/// Disarm the motors (MAV_CMD_COMPONENT_ARM_DISARM 0; the vehicle refuses in flight).
bool Mavlink::disarm() {
  sent("disarm", "[]");
  return command("disarm", "disarm", MAV_CMD_COMPONENT_ARM_DISARM, {0});
}

/// Climb to `alt` m above home (MAV_CMD_NAV_TAKEOFF; GUIDED and armed).
bool Mavlink::takeoff(double alt) {
  sent("takeoff", "[" + json_number(alt) + "]");
  takeoff_alt_ = alt;  // PX4 adds home's altitude AMSL to the double, as Python does
  return command("takeoff", "takeoff", MAV_CMD_NAV_TAKEOFF,
                 {0, 0, 0, 0, 0, 0, static_cast<float>(alt)});
}

/// Land where the vehicle is (MAV_CMD_NAV_LAND: LAND mode).
bool Mavlink::land() {
  sent("land", "[]");
  return command("land", "land", MAV_CMD_NAV_LAND, {});
}

/// Stop where the vehicle is: a zero velocity target (GUIDED).
bool Mavlink::hold() {
  sent("hold", "[]");
  aim_ = Aim{};
  return target_local(MAV_FRAME_BODY_OFFSET_NED, kVelocityMask, {0, 0, 0}, {0, 0, 0}, 0);
}

/// Velocity target in the body frame: m/s forward, right, down; rad/s clockwise.
/// ArduPilot stops the vehicle when no new target comes for 3 s.
bool Mavlink::set_velocity(double vx, double vy, double vz, double yaw_rate) {
  sent("set_velocity", "[" + json_number(vx) + "," + json_number(vy) + "," + json_number(vz) + "," +
                           json_number(yaw_rate) + "]");
  aim_ = Aim{};
  return target_local(MAV_FRAME_BODY_OFFSET_NED, kVelocityMask, {0, 0, 0}, {vx, vy, vz},
                      yaw_rate);
}

/// Stop the reader and close the socket (also done by the destructor).
void Mavlink::close() {
  if (stop_.exchange(true)) return;
  if (reader_.joinable()) reader_.join();  // the reader wakes within kPollMs
  std::lock_guard<std::mutex> lock(link_);
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
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
  const int percent = now.battery;
  return "{\"type\":\"vehicle\",\"t\":" + std::to_string(t_ms) + ",\"name\":" + json_string(name_) +
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
    n.mission = {s_.mission_current, s_.mission_total};
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

/// A playback entry over `s` (schemas/recording.md); a bad value throws InputError.
void Mavlink::apply(Snap& s, const playback::Entry& e) const {
  const playback::Inputs& in = *inputs_;
  for (const auto& [key, v] : e.values.members) {
    const char* k = key.c_str();
    const auto vector = [&]() {
      if (v.kind != json::Value::ARRAY || v.items.size() != 3) in.bad(e.line, "`" + key + "` must be [x, y, z]");
      return Eigen::Vector3d(in.number(v.items[0], k, e.line), in.number(v.items[1], k, e.line),
                             in.number(v.items[2], k, e.line));
    };
    if (key == "heartbeat_age") s.heartbeat_age = in.number(v, k, e.line);
    else if (key == "ready") s.ready = in.boolean(v, k, e.line);
    else if (key == "armed") s.armed = in.boolean(v, k, e.line);
    else if (key == "mode") s.mode = in.text(v, k, e.line);
    else if (key == "position") s.position = vector();
    else if (key == "altitude") s.altitude = in.number(v, k, e.line);
    else if (key == "velocity") s.velocity = vector();
    else if (key == "yaw") s.yaw = in.number(v, k, e.line);
    else if (key == "battery") s.battery = static_cast<int>(in.whole(v, k, e.line));
    else if (key == "vehicle") s.vehicle = in.boolean(v, k, e.line);
    else if (key == "type") s.type = static_cast<int>(in.whole(v, k, e.line));
    else if (key == "autopilot") s.autopilot = static_cast<int>(in.whole(v, k, e.line));
    else if (key == "location") s.location = vector();
    else if (key == "home") s.home = vector();
    else if (key == "status_text") s.status_text = in.text(v, k, e.line);
    else if (key == "battery_failsafe") s.battery_failsafe = in.text(v, k, e.line);
    else if (key == "fence_breached") s.fence_breached = in.boolean(v, k, e.line);
    else if (key == "failsafe") s.failsafe = in.text(v, k, e.line);
    else if (key == "mission") {
      if (v.kind != json::Value::ARRAY || v.items.size() != 2) in.bad(e.line, "`mission` must be [current, total]");
      s.mission = {static_cast<int>(in.whole(v.items[0], k, e.line)), static_cast<int>(in.whole(v.items[1], k, e.line))};
    }
    else if (key == "acks") {
      if (v.kind != json::Value::OBJECT) in.bad(e.line, "`acks` must be an object");
      s.acks.clear();
      for (const auto& [command, outcome] : v.members) s.acks[command] = in.text(outcome, "acks", e.line);
    }
    // other fields (`t`, ...) are not part of what the automaton sees
  }
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
    snap_.acks[name] = snap_.vehicle ? "pending" : "not_sent";
    if (inputs_ != nullptr || !snap_.vehicle) {
      if (!snap_.vehicle) say(label + ": not sent, no vehicle yet (no heartbeat)");
      if (inputs_ == nullptr) {
        std::lock_guard<std::mutex> lock(link_);
        acks_[name] = "not_sent";
      }
      return snap_.vehicle;
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
  mavlink_msg_command_long_pack_status(sysid_, kGcsComponent, &wire_->tx_status, &msg, system,
                                       component, p.command, confirmation, p.params[0],
                                       p.params[1], p.params[2], p.params[3], p.params[4],
                                       p.params[5], p.params[6]);
  send(msg);
}

bool Mavlink::target_local(uint8_t frame, uint16_t mask, Eigen::Vector3d pos, Eigen::Vector3d vel,
                  double yaw_rate, double yaw) {
  if (!snap_.vehicle) return false;  // a stream of targets: nothing to say
  uint8_t system, component;
  if (inputs_ != nullptr || !target(&system, &component)) return true;
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
        sysid_, kGcsComponent, &wire_->tx_status, &msg, boot_ms, system, component, t.frame,
        t.mask, static_cast<int32_t>(std::nearbyint(t.pos[0] * 1e7)),
        static_cast<int32_t>(std::nearbyint(t.pos[1] * 1e7)), static_cast<float>(t.pos[2]), 0, 0,
        0, 0, 0, 0, static_cast<float>(t.yaw), 0);
    send(msg);
    return;
  }
  mavlink_msg_set_position_target_local_ned_pack_status(
      sysid_, kGcsComponent, &wire_->tx_status, &msg, boot_ms, system, component, t.frame, t.mask,
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
    mavlink_msg_param_set_pack_status(sysid_, kGcsComponent, &wire_->tx_status, &msg, system,
                                      component, id, static_cast<float>(value),
                                      on_px4 ? MAV_PARAM_TYPE_REAL32 : MAV_PARAM_TYPE_INT16);
    send(msg);
  }
  say(std::string("rtl: ") + name + " set to " + fmt(value));
}

mavlink_status_t* Mavlink::tx_status() { return &wire_->tx_status; }  // under link_

void Mavlink::send(const mavlink_message_t& msg) {  // under link_
  if (fd_ < 0 || !peer_known_) return;  // udpin: nobody has written to us yet
  uint8_t buf[MAVLINK_MAX_PACKET_LEN];
  uint16_t len = mavlink_msg_to_send_buffer(buf, &msg);
  // A full buffer or an unreachable peer loses the datagram, as UDP does.
  if (::sendto(fd_, buf, len, MSG_DONTWAIT, reinterpret_cast<const sockaddr*>(&wire_->peer),
               sizeof wire_->peer) >= 0)
    ++sent_;
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

// -- the reader thread -------------------------------------------------------------
void Mavlink::run() {
  while (!stop_.load()) {
    pollfd pfd{fd_, POLLIN, 0};
    int n = ::poll(&pfd, 1, kPollMs);
    if (n > 0 && (pfd.revents & POLLIN)) drain();
    timed(Clock::now());
  }
}

/// The reader's timed work: our heartbeat, resends and deadlines, the link's watch.
void Mavlink::timed(Clock::time_point now) {
  if (!heartbeat_sent_ || now >= next_heartbeat_) {
    heartbeat_sent_ = true;
    next_heartbeat_ = now + duration(kGcsHeartbeatS);
    std::lock_guard<std::mutex> lock(link_);
    mavlink_message_t msg;
    mavlink_msg_heartbeat_pack_status(sysid_, kGcsComponent, &wire_->tx_status, &msg, MAV_TYPE_GCS,
                                      MAV_AUTOPILOT_INVALID, 0, 0, 0);
    send(msg);
  }
  expire(now);
  upload_tick(now);
  watch_link();
  if (px4()) {
    uint32_t mode;
    bool armed;
    double heartbeat_at = -std::numeric_limits<double>::infinity();
    {
      std::lock_guard<std::mutex> lock(state_);
      mode = s_.custom_mode;
      armed = s_.base_mode & MAV_MODE_FLAG_SAFETY_ARMED;
      if (s_.heartbeat_seen) heartbeat_at = seconds(s_.heartbeat_at.time_since_epoch());
    }
    bool switch_accepted;
    {
      std::lock_guard<std::mutex> lock(link_);
      auto it = acks_.find("set_mode");
      switch_accepted = it != acks_.end() && it->second == "accepted";
    }
    offboard_->tick(now_s(), mode, armed, heartbeat_at, switch_accepted);
  }
}

/// Handle every datagram waiting (at most 1000, so a flood cannot starve the
/// deadlines); bytes that are no MAVLink frame are dropped, never raised.
void Mavlink::drain() {
  std::vector<uint8_t>& buf = rx_buf_;
  std::vector<mavlink_message_t> got;
  for (int i = 0; i < 1000; ++i) {
    sockaddr_in from{};
    socklen_t from_len = sizeof from;
    ssize_t n = ::recvfrom(fd_, buf.data(), buf.size(), MSG_DONTWAIT,
                           reinterpret_cast<sockaddr*>(&from), &from_len);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) break;
    if (n < 0) continue;  // an ICMP error reported on the socket: try the next datagram
    ++received_;
    got.clear();
    {
      std::lock_guard<std::mutex> lock(link_);
      wire_->rx_status.parse_state = MAVLINK_PARSE_STATE_IDLE;  // each datagram from scratch
      for (ssize_t k = 0; k < n; ++k) {
        mavlink_message_t msg;
        mavlink_status_t status;
        if (mavlink_frame_char_buffer(&wire_->rx_msg, &wire_->rx_status, buf[k], &msg, &status) ==
            MAVLINK_FRAMING_OK) {
          got.push_back(msg);
        }
      }
      if (!got.empty() && listening_ && from_len == sizeof from) {
        wire_->peer = from;  // answer whoever speaks MAVLink to us, as mavutil's udpin does
        peer_known_ = true;
      }
    }
    for (const mavlink_message_t& msg : got) handle(msg);
  }
}

/// A copy of one of the last kDuplicateWindow frames of that source (same seq,
/// message and checksum): a network duplicate, however late. Reader thread only.
bool Mavlink::duplicate(const mavlink_message_t& msg) {
  const Clock::time_point now = this->now();
  Recent& r = recent_[static_cast<uint16_t>(msg.sysid << 8 | msg.compid)];
  if (!r.any || seconds(now - r.at) > kSilenceS) r = Recent{};  // first word, or a reboot
  r.any = true;
  r.at = now;
  const uint64_t key = static_cast<uint64_t>(msg.seq) << 40 |
                       static_cast<uint64_t>(msg.msgid) << 16 | msg.checksum;
  if (r.count.count(key) != 0) return true;
  r.order.push_back(key);
  ++r.count[key];
  if (r.order.size() > kDuplicateWindow) {
    auto it = r.count.find(r.order.front());
    if (--it->second == 0) r.count.erase(it);
    r.order.pop_front();
  }
  return false;
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
        url_ + ", mode " + now_mode);
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

void Mavlink::watch_link() {  // the reader thread: the state at hand, not the automaton's snapshot
  bool seen;
  double age;
  {
    std::lock_guard<std::mutex> lock(state_);
    seen = s_.heartbeat_seen;
    age = seen ? seconds(now() - s_.heartbeat_at) : kInf;
  }
  if (!lost_ && seen && !(age < kLinkTimeoutS)) {
    lost_ = true;
    {
      std::lock_guard<std::mutex> lock(state_);
      s_.gps_fix = 0;  // whatever answers next says afresh whether it is ready
      s_.ekf_flags = 0;
    }
    say("link lost: no heartbeat for " + fmt(kLinkTimeoutS) + " s");
  }
}

// -- opening -------------------------------------------------------------------------
/// Open the socket the URL names; "" or why not.
std::string Mavlink::open_socket() {
  std::string kind, rest;
  size_t colon = url_.find(':');
  if (colon != std::string::npos) {
    kind = url_.substr(0, colon);
    rest = url_.substr(colon + 1);
  }
  if (kind == "udp") kind = "udpin";
  size_t last = rest.rfind(':');
  std::string host = last == std::string::npos ? "" : rest.substr(0, last);
  std::string port = last == std::string::npos ? "" : rest.substr(last + 1);
  bool digits = !port.empty() && port.size() <= 5 &&
                std::all_of(port.begin(), port.end(), [](char c) { return c >= '0' && c <= '9'; });
  if ((kind != "udpin" && kind != "udpout") || host.empty() || !digits ||
      std::stoi(port) > 65535 || (kind == "udpout" && std::stoi(port) == 0)) {
    return "expected udpin:HOST:PORT, udpout:HOST:PORT or udp:HOST:PORT";
  }
  addrinfo hints{};
  hints.ai_family = AF_INET;
  hints.ai_socktype = SOCK_DGRAM;
  addrinfo* found = nullptr;
  int err = ::getaddrinfo(host.c_str(), port.c_str(), &hints, &found);
  if (err != 0 || found == nullptr) return std::string("host ") + host + ": " + gai_strerror(err);
  sockaddr_in addr{};
  std::memcpy(&addr, found->ai_addr, sizeof addr);
  ::freeaddrinfo(found);
  fd_ = ::socket(AF_INET, SOCK_DGRAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
  if (fd_ < 0) return std::strerror(errno);
  listening_ = kind == "udpin";
  if (listening_) {
    if (::bind(fd_, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0) {
      std::string why = std::strerror(errno);
      ::close(fd_);
      fd_ = -1;
      return why;
    }
  } else {
    wire_->peer = addr;
    peer_known_ = true;
  }
  return "";
}

// -- helpers -----------------------------------------------------------------------
double Mavlink::option(const std::map<std::string, std::string>& options, const std::string& key,
              double fallback) const {
  auto it = options.find(key);
  if (it == options.end()) return fallback;
  const std::string& raw = it->second;
  std::string text = strip(raw);
  char* end = nullptr;
  errno = 0;
  double value = text.empty() ? -1.0 : std::strtod(text.c_str(), &end);
  if (!text.empty() && (end == nullptr || *end != '\0')) value = -1.0;
  if (!(value > 0) || std::isinf(value)) {
    say("option " + key + ": `" + raw + "` is not a positive number, " + fmt(fallback) +
        " used");
    return fallback;
  }
  return value;
}

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

std::string Mavlink::result_name(uint8_t result) {
  static const char* const names[] = {"accepted", "temporarily_rejected", "denied",
                                      "unsupported", "failed", "in_progress", "cancelled"};
  if (result < sizeof names / sizeof names[0]) return names[result];
  return "result_" + std::to_string(result);
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

void Mavlink::say(const std::string& text) const {
  std::string line = name_ + ": " + text + "\n";
  std::fwrite(line.data(), 1, line.size(), stderr);  // one write: lines never interleave
  std::fflush(stderr);
}

}  // namespace hfsmc
