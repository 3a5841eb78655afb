// hfsmc_px4.cpp: what the `mavlink` interface does differently on PX4 (hfsmc/px4.hpp says
// how), compiled into the library hfsmc_mavlink beside hfsmc_mavlink.cpp: the px4 helpers,
// then the PX4 side of hfsmc::Mavlink. The twin of templates/python/hfsmc_px4.py: the same
// names, times and lines on stderr. mavgen's headers as in hfsmc_mavlink.cpp.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Waddress-of-packed-member"
#pragma GCC diagnostic ignored "-Wpedantic"
#include "mavlink/ardupilotmega/mavlink.h"
#pragma GCC diagnostic pop

#include "hfsmc/mavlink.hpp"
#include "hfsmc/px4.hpp"

namespace hfsmc {
namespace px4 {
namespace {

struct Named {
  const char* name;
  uint32_t number;
};

// In Python's order (hfsmc_px4.MODES): the error message lists them so.
const Named kModes[] = {
    {"GUIDED", kOffboard},      {"HOLD", kHold},          {"TAKEOFF", kTakeoff},
    {"LAND", custom(4, 6)},     {"RTL", custom(4, 5)},    {"AUTO", custom(4, 4)},
    {"READY", custom(4, 1)},    {"FOLLOW", custom(4, 8)}, {"PRECLAND", custom(4, 9)},
    {"POSCTL", custom(3)},      {"ALTCTL", custom(2)},    {"MANUAL", custom(1)},
    {"ACRO", custom(5)},        {"STABILIZED", custom(7)}};
const std::pair<const char*, const char*> kAliases[] = {  // PX4's own spellings
    {"OFFBOARD", "GUIDED"}, {"LOITER", "HOLD"}, {"MISSION", "AUTO"}};

std::string upper_stripped(const std::string& s) {
  const char* space = " \t\n\r\f\v";
  size_t a = s.find_first_not_of(space);
  if (a == std::string::npos) return "";
  std::string out = s.substr(a, s.find_last_not_of(space) - a + 1);
  for (char& c : out) {
    if (c >= 'a' && c <= 'z') c = static_cast<char>(c - 'a' + 'A');
  }
  return out;
}

}  // namespace

std::string mode_name(uint32_t custom_mode) {
  for (const Named& m : kModes) {
    if (m.number == custom_mode) return m.name;
  }
  char buf[32];
  std::snprintf(buf, sizeof buf, "MODE%#010x", custom_mode);  // Python's f"{x:#010x}"
  return custom_mode == 0 ? "MODE0x00000000" : buf;
}

bool mode_number(const std::string& name, uint32_t* number) {
  std::string wanted = upper_stripped(name);
  for (const auto& alias : kAliases) {
    if (wanted == alias.first) wanted = alias.second;
  }
  for (const Named& m : kModes) {
    if (wanted == m.name) {
      *number = m.number;
      return true;
    }
  }
  return false;
}

std::string mode_list() {
  std::string names;
  for (const Named& m : kModes) names += (names.empty() ? "" : ", ") + std::string(m.name);
  return names;
}

void set_mode_params(uint32_t custom_mode, float* p1, float* p2, float* p3) {
  *p1 = 1;  // MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
  *p2 = static_cast<float>(custom_mode >> 16 & 0xFF);
  *p3 = static_cast<float>(custom_mode >> 24 & 0xFF);
}

// -- Offboard ------------------------------------------------------------------------
void Offboard::want(bool on) {
  std::vector<std::string> lines;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    want_locked(on, &lines);
  }
  for (const std::string& line : lines) say_(line);
}

bool Offboard::lost() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return lost_;
}

void Offboard::clear_lost() {
  std::lock_guard<std::mutex> lock(mutex_);
  lost_ = false;
}

void Offboard::want_locked(bool on, std::vector<std::string>* lines) {
  if (!on && has_target_) lines->push_back("PX4: setpoint stream stopped");
  if (on) lost_ = false;
  if (on && !wanted_) asked_at_ = -kInf;  // an earlier switch's answer is not this one's
  wanted_ = on;
  if (!on) {
    has_target_ = false;
    started_ = kInf;
  }
}

void Offboard::target(double now, const Target& t) {
  bool first;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!wanted_) return;
    first = !has_target_;
    if (first) started_ = now;
    has_target_ = true;
    target_ = t;
    sent_at_ = now;
  }
  if (first) say_("PX4: keeping a setpoint stream at 10 Hz (OFFBOARD needs one)");
}

void Offboard::tick(double now, uint32_t mode, bool armed, double heartbeat_at,
                    bool switch_accepted) {
  std::vector<std::string> lines;
  bool resend = false, ask = false;
  Target t;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    const int64_t was = mode_;
    mode_ = mode;
    // PX4 accepted the switch (its last answer), and a HEARTBEAT since says otherwise.
    const bool accepted = asked_at_ > -kInf && switch_accepted;
    const bool left = was == kOffboard || (accepted && heartbeat_at > asked_at_ + kSettleS);
    if (left && mode != kOffboard && wanted_) {
      lines.push_back("PX4 left OFFBOARD for " + mode_name(mode) +
                      " (a failsafe or a pilot): the driver stops its stream; "
                      "set_mode(\"GUIDED\") takes the vehicle back");
      want_locked(false, &lines);
      lost_ = true;
    } else if (has_target_) {
      if (now - sent_at_ >= kResendS) {
        resend = true;
        t = target_;
        sent_at_ = now;
      }
      if (mode != kOffboard && armed && !accepted && now - started_ >= kWarmupS &&
          now - asked_at_ >= kSwitchRetryS) {
        asked_at_ = now;
        ask = true;
      }
    }
  }
  for (const std::string& line : lines) say_(line);
  if (resend) send_(t);
  if (ask) {
    say_("PX4: setpoints streaming: switching to OFFBOARD");
    switch_();
  }
}

bool Offboard::streaming() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return has_target_;
}

// -- Texts ---------------------------------------------------------------------------
std::vector<std::pair<int, std::string>> Texts::add(double now, int severity,
                                                    const std::string& text, int text_id,
                                                    int seq) {
  std::vector<std::pair<int, std::string>> done;
  for (auto it = parts_.begin(); it != parts_.end();) {
    if (now - it->second.at > kTextWaitS) {
      std::string joined;
      for (const std::string& p : it->second.parts) joined += p;
      done.emplace_back(it->second.severity, joined);
      it = parts_.erase(it);
    } else {
      ++it;
    }
  }
  if (text_id == 0) {
    done.emplace_back(severity, text);
    return done;
  }
  auto found = parts_.find(text_id);
  Part part = found == parts_.end() ? Part{now, severity, {}} : found->second;
  if (seq == static_cast<int>(part.parts.size())) part.parts.push_back(text);
  if (text.size() < 50) {
    parts_.erase(text_id);
    std::string joined;
    for (const std::string& p : part.parts) joined += p;
    done.emplace_back(part.severity, joined);
  } else {
    parts_[text_id] = part;
  }
  return done;
}

}  // namespace px4

// -- the PX4 side of Mavlink ---------------------------------------------------------------
double Mavlink::now_s() const {  // as Python's driver counts: simulated µs / 1e6, or monotonic
  if (sim_ != nullptr) return static_cast<double>(sim_->now_us()) / 1e6;
  return seconds(Clock::now().time_since_epoch());
}

/// GUIDED on PX4: Hold on the ground (armable; targets switch to OFFBOARD once their
/// stream runs), in the air a stream holding where the vehicle is, then OFFBOARD.
bool Mavlink::px4_mode(const std::string& name, uint32_t number) {
  const bool guided = number == px4::kOffboard;
  offboard_->want(guided);
  if (guided && current().armed) {
    if (!offboard_->streaming()) hold();
    // the switch comes from the stream (last_ack("set_mode") says its answer)
    instant().acks["set_mode"] = current().vehicle ? "pending" : "not_sent";
    return current().vehicle;
  }
  if (guided) {
    number = px4::kHold;
    say("PX4: GUIDED on the ground is Hold; targets switch to OFFBOARD in flight");
  }
  float p1, p2, p3;
  px4::set_mode_params(number, &p1, &p2, &p3);
  return command("set_mode", "set_mode " + name, MAV_CMD_DO_SET_MODE, {p1, p2, p3});
}

/// A command as PX4 wants it (take-off altitude AMSL); the stream stops for a landing,
/// RTL or a disarm. False: not to be sent (said why).
bool Mavlink::px4_command(Pending& p) {
  if (p.command == MAV_CMD_NAV_TAKEOFF) {
    bool seen;
    double home;
    {
      std::lock_guard<std::mutex> lock(state_);
      seen = s_.home_amsl_seen;
      home = s_.home_amsl;
    }
    if (!seen) {
      {
        std::lock_guard<std::mutex> lock(link_);
        acks_[p.name] = "not_sent";
      }
      say("takeoff: not sent, PX4 wants the altitude AMSL and no global position has come yet");
      return false;
    }
    offboard_->want(true);
    p.params[3] = std::numeric_limits<float>::quiet_NaN();  // PX4: keep the heading
    p.params[6] = static_cast<float>(takeoff_alt_ + home);
    return true;
  }
  if (p.command == MAV_CMD_NAV_LAND || p.command == MAV_CMD_NAV_RETURN_TO_LAUNCH ||
      (p.command == MAV_CMD_COMPONENT_ARM_DISARM && p.params[0] == 0))
    offboard_->want(false);
  return true;
}

/// A second answer (PX4 v1.16 answers DO_SET_MODE at once, then for real): the last
/// answer counts. Under link_; the line to say, or "".
std::string Mavlink::late_ack(uint16_t command, uint8_t code) {
  auto it = answered_.find(command);
  if (it == answered_.end()) return "";
  const Answered& a = it->second;
  const std::string result = result_name(code);
  if (now() > a.until || (a.quiet && result == "accepted")) return "";
  if (!a.quiet) {
    auto seen = acks_.find(a.name);
    if (seen != acks_.end() && seen->second == result) return "";
    acks_[a.name] = result;
  }
  return a.label + " " + (result == "accepted" ? result : upper(result)) + " (second answer)";
}

/// STATUSTEXT, joined when it comes in chunks; warnings and worse said on stderr.
void Mavlink::on_statustext(const mavlink_message_t& msg) {
  mavlink_statustext_t m;
  mavlink_msg_statustext_decode(&msg, &m);
  const std::string text(m.text, strnlen(m.text, sizeof m.text));
  for (const auto& [severity, whole] : texts_.add(now_s(), m.severity, text, m.id, m.chunk_seq)) {
    {
      std::lock_guard<std::mutex> lock(state_);
      s_.status_text = whole;
    }
    if (severity <= px4::kSeverityWarning) say(std::string(px4() ? "PX4: " : "ArduPilot: ") + whole);
  }
}

}  // namespace hfsmc
