// hfsmc: what the `mavlink` interface does differently on PX4 (docs/interfaces.md, "PX4
// and ArduPilot"): the C++ twin of templates/python/hfsmc_px4.py, used by hfsmc::Mavlink
// once a HEARTBEAT says autopilot 12 (or the option `autopilot: px4` says so). Defined in
// src/hfsmc_px4.cpp, compiled into the library hfsmc_mavlink; no mavgen header needed.
//
// - Mode names: PX4's custom_mode is main << 16 | sub << 24. The names ArduPilot has too
//   mean the same thing: GUIDED is OFFBOARD (the ground station flies the vehicle), LAND,
//   RTL, AUTO (the mission); PX4's own are HOLD (AUTO.LOITER), TAKEOFF, POSCTL, ALTCTL,
//   MANUAL, STABILIZED, ACRO, READY, FOLLOW, PRECLAND.
// - OFFBOARD needs a setpoint stream (2 Hz at least) before PX4 accepts it and falls to a
//   failsafe when the stream stops: Offboard keeps the snippet's latest target going at
//   10 Hz from the driver's reader (or, in lockstep, at simulated time), and switches to
//   OFFBOARD once the stream has run for 0.6 s, but only while the model has asked for
//   GUIDED. When PX4 leaves OFFBOARD by itself (a failsafe, a pilot), the driver stops: it
//   never fights the autopilot; set_mode("GUIDED") takes the vehicle back.
// - STATUSTEXT may come in chunks (one id, chunk_seq 0, 1, ...): Texts joins them.
//
// Times are seconds as doubles computed as Python computes them (simulated µs / 1e6 in
// lockstep), so that both drivers send the same datagrams at the same instants.
#pragma once

#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <map>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

namespace hfsmc {
namespace px4 {

constexpr uint8_t kAutopilotPx4 = 12;  // MAV_AUTOPILOT_PX4
constexpr uint8_t kFrameBodyNed = 8;   // MAV_FRAME_BODY_NED: PX4 turns velocities by the heading
constexpr double kResendS = 0.1;       // the stream's period when the snippet sends less often
constexpr double kWarmupS = 0.6;       // stream this long before asking for OFFBOARD (PX4: 0.5 s)
constexpr double kSwitchRetryS = 1.0;  // a refused switch is asked again after this
constexpr double kSettleS = 0.5;       // a HEARTBEAT this long after an accepted switch: PX4's mode
constexpr double kTextWaitS = 1.0;     // a chunked STATUSTEXT whose last chunk never comes
constexpr int kSeverityWarning = 4;    // STATUSTEXT severities up to this one are said

/// PX4's custom_mode for a main mode and a sub-mode.
constexpr uint32_t custom(uint32_t main, uint32_t sub = 0) { return main << 16 | sub << 24; }

constexpr uint32_t kOffboard = custom(6), kHold = custom(4, 3), kTakeoff = custom(4, 2);

/// The driver's name of a PX4 custom_mode (MODE0x... when it has none).
std::string mode_name(uint32_t custom_mode);

/// A mode name (any case, PX4's spellings too: OFFBOARD, LOITER, MISSION) as PX4's
/// custom_mode; false if PX4 lacks it.
bool mode_number(const std::string& name, uint32_t* number);

/// The names set_mode accepts, for an error message: "GUIDED, HOLD, ...".
std::string mode_list();

/// MAV_CMD_DO_SET_MODE's p1, p2 (main) and p3 (sub) for a custom_mode.
void set_mode_params(uint32_t custom_mode, float* p1, float* p2, float* p3);

/// One SET_POSITION_TARGET_LOCAL_NED's fields, as the snippet sent them.
struct Target {
  uint8_t frame = 0;
  uint16_t mask = 0;
  double pos[3] = {0, 0, 0};  // a global target: lat, lon (degrees), m above home
  double vel[3] = {0, 0, 0};
  double yaw_rate = 0;
  double yaw = 0;
  bool global = false;  // SET_POSITION_TARGET_GLOBAL_INT (the mission API's goto_location)
};

/// The setpoint stream and the OFFBOARD switch of one vehicle. `send` sends a target
/// again; `switch_offboard` asks for OFFBOARD; `say` writes a line on stderr. Its own
/// mutex: the automaton's thread sets targets, the reader ticks; the callbacks are called
/// with it released.
class Offboard {
 public:
  Offboard(std::function<void(const Target&)> send, std::function<void()> switch_offboard,
           std::function<void(const std::string&)> say)
      : send_(std::move(send)), switch_(std::move(switch_offboard)), say_(std::move(say)) {}

  /// GUIDED asked for (true) or another mode, a landing, RTL (false: the stream stops).
  void want(bool on);
  /// The snippet sent a target (already sent once): keep it going.
  void target(double now, const Target& t);
  /// The reader's timed work: resend the target, switch to OFFBOARD when it is time, and
  /// let go when PX4 leaves OFFBOARD by itself. `heartbeat_at`: when the HEARTBEAT that
  /// said `mode` came; `switch_accepted`: the last answer to set_mode (the switch's, once
  /// asked) is accepted. An accepted switch counts as OFFBOARD reached even when no
  /// HEARTBEAT said so before the link dropped: a later HEARTBEAT in another mode is PX4
  /// leaving it.
  void tick(double now, uint32_t mode, bool armed, double heartbeat_at = -kInf,
            bool switch_accepted = false);
  /// A target is being streamed.
  bool streaming() const;
  /// PX4 left OFFBOARD by itself (failsafe()): true until the model asks for a mode again.
  bool lost() const;
  void clear_lost();

 private:
  static constexpr double kInf = std::numeric_limits<double>::infinity();
  void want_locked(bool on, std::vector<std::string>* lines);

  std::function<void(const Target&)> send_;
  std::function<void()> switch_;
  std::function<void(const std::string&)> say_;
  mutable std::mutex mutex_;
  bool wanted_ = false;  // the model asked for GUIDED: targets put the vehicle in OFFBOARD
  bool has_target_ = false;
  Target target_;  // the latest target
  double started_ = kInf;  // when the stream (re)started
  double sent_at_ = -kInf;
  double asked_at_ = -kInf;
  int64_t mode_ = -1;  // the vehicle's mode at the last look
  bool lost_ = false;
};

/// STATUSTEXT, joined when it comes in chunks (MAVLink 2: id and chunk_seq).
class Texts {
 public:
  /// The whole texts (severity, text) this chunk completes (a chunk shorter than 50 bytes
  /// ends one); `text` is the chunk's text up to its first NUL.
  std::vector<std::pair<int, std::string>> add(double now, int severity, const std::string& text,
                                               int text_id, int seq);

 private:
  struct Part {
    double at;
    int severity;
    std::vector<std::string> parts;
  };
  std::map<int, Part> parts_;
};

}  // namespace px4
}  // namespace hfsmc
