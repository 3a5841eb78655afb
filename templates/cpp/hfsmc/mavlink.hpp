// hfsmc: the `mavlink` interface of C++ components (docs/interfaces.md): a vehicle flown
// the ArduPilot Copter way (GUIDED mode), over UDP with mavgen's C headers.
//
// ArduPilot Copter and PX4 alike: what PX4 needs (its mode names, a setpoint stream
// for OFFBOARD, the take-off altitude AMSL, answers that come twice, STATUSTEXT in
// chunks) is in px4.hpp and src/hfsmc_px4.cpp (docs/interfaces.md, "PX4 and ArduPilot").
//
// The C++ twin of templates/python/hfsmc_mavlink.py: the same queries and
// commands, the same timeouts and the same lines on stderr. One reader thread
// owns the receiving side: it polls the socket (50 ms at most, which bounds
// the ack deadlines and the destructor), keeps the latest telemetry, watches
// the heartbeat, requests the message rates, matches COMMAND_ACKs to the
// commands waiting for them (resending once halfway, as MAVProxy does with
// confirmation + 1) and logs each outcome once. The automaton's thread never
// waits on the network: a query copies the state at hand, a command sends one
// datagram on a non-blocking socket and returns.
//
// The driver is built on hfsmc::Driver<MavlinkSnap> (driver.hpp, docs/drivers.md), as a
// user's driver is: the base takes the snapshot of each instant (docs/recording.md:
// live, read() copies the state at hand; with --playback DIR the vehicle is a fake, with
// no socket and no thread, its snapshots from DIR/inputs.jsonl), records it, tells every
// command to the recording or the playback (DIR/commands.jsonl), keeps the options as
// given (Policy::own_options: a bad or unknown one is said and replaced here), owns the
// reader thread and joins the lockstep. Every query reads the instant's snapshot; a
// command is sent at once, and its last_ack() says `pending` (or `not_sent`) until the
// next snapshot. The live views show the vehicle panel (this class is a Feed of its
// own: Policy::fields_view off), from the state at hand.
//
// Two mutexes, never held together and never while waiting: `state_` guards
// the telemetry, `link_` the MAVLink parser and sender state, the socket's
// peer and the commands waiting for an answer. Each datagram is parsed from
// a fresh parser state (a datagram is a whole number of frames), so a
// truncated frame cannot eat the next datagram's message.
//
// URLs: udpin:HOST:PORT (or udp:, as mavutil: listen there and answer the
// vehicle that writes to it) and udpout:HOST:PORT (send there and read the
// replies). A URL that cannot be opened is said on stderr and the process
// exits with status 1, as the Python driver's SystemExit(1) does.
//
// The class is declared here and defined in src/hfsmc_mavlink*.cpp (the snapshot and
// the queries; _link: the socket, the parser and the reader's work; _commands: what is
// sent and its acks), hfsmc_mission*.cpp and hfsmc_px4.cpp, compiled once into the
// library hfsmc_mavlink: the component's unit sees neither mavgen's headers nor the
// driver's code (docs/cpp.md, "Build speed").
/* hfsmc driver
# The mavlink driver's declaration, as a user's C++ driver header carries one
# (docs/drivers.md); tests/test_drivers_api.py compares it with the Python driver's
# (hfsmc_mavlink.VehicleQueries). `goto` is go_to() in C++ (a keyword); what each
# method does: docs/interfaces.md.
kind: mavlink
class: Mavlink
doc: A MAVLink vehicle with ArduPilot Copter conventions
snapshot: {heartbeat_age: .inf, ready: false, armed: false, mode: '',
  position: [.nan, .nan, .nan], altitude: .nan, velocity: [.nan, .nan, .nan], yaw: .nan,
  battery: -1, acks: {}, vehicle: false, type: 0, autopilot: 0, location: [.nan, .nan, .nan],
  home: [.nan, .nan, .nan], status_text: '', battery_failsafe: '', mission: [0, 0],
  fence_breached: false, failsafe: ''}
options: {rate: 20.0, ack_timeout: 3.0, source_system: 255, autopilot: auto}
queries: ["connected()", "heartbeat_age()", "ready()", "armed()", "mode()", "position()",
  "altitude()", "velocity()", "yaw()", "battery()", "location()", "home()",
  "distance_to(north, east, alt)", "distance_to_location(lat, lon, alt)",
  "reached(north, east, alt, tolerance)", "reached_location(lat, lon, alt, tolerance)",
  "status_text()", "battery_failsafe()", "failsafe()", "last_ack(command)",
  "mission_progress()", "fence_breached()", "warning_at_stop()", "close()"]
commands: ["set_mode(name)", "arm()", "disarm()", "takeoff(alt)", "land()", "rtl(alt)",
  "hold()", "set_velocity(vx, vy, vz, yaw_rate)", "goto(north, east, alt, heading)",
  "goto_location(lat, lon, alt, heading)", "set_yaw(heading)", "upload_mission(points, end)",
  "upload_fence(vertices)", "enable_fence(on)"]
*/
#pragma once

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <deque>
#include <initializer_list>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "driver.hpp"
#include "json.hpp"
#include "observer.hpp"
#include "playback.hpp"
#include "px4.hpp"
#include "record.hpp"
#include "simclock.hpp"
#include "thread.hpp"

struct __mavlink_message;  // mavlink_message_t of mavgen's headers (src/hfsmc_mavlink.cpp)
struct __mavlink_status;  // mavlink_status_t

namespace hfsmc {

// What the automaton sees of a vehicle during one instant (hfsmc.mavlink.Snapshot), in
// the recording's order.
struct MavlinkSnap {
  static constexpr double kInf = std::numeric_limits<double>::infinity();
  static constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  double heartbeat_age = kInf;
  bool ready = false, armed = false;
  std::string mode;
  Eigen::Vector3d position{kNaN, kNaN, kNaN};
  double altitude = kNaN;
  Eigen::Vector3d velocity{kNaN, kNaN, kNaN};
  double yaw = kNaN;
  long long battery = -1;
  std::map<std::string, std::string> acks;
  bool vehicle = false;  // a vehicle has been heard: commands are sent
  long long type = 0;  // its HEARTBEAT type (the mode names)
  long long autopilot = 0;  // its HEARTBEAT autopilot (12: PX4's mode names and ways)
  Eigen::Vector3d location{kNaN, kNaN, kNaN};
  Eigen::Vector3d home{kNaN, kNaN, kNaN};
  std::string status_text, battery_failsafe;
  long long mission[2] = {0, 0};  // current, total
  bool fence_breached = false;
  std::string failsafe;

  static std::vector<Field> fields(MavlinkSnap& s) {
    return {{"heartbeat_age", &s.heartbeat_age}, {"ready", &s.ready}, {"armed", &s.armed},
            {"mode", &s.mode}, {"position", Numbers{s.position.data(), 3, "[x, y, z]"}},
            {"altitude", &s.altitude}, {"velocity", Numbers{s.velocity.data(), 3, "[x, y, z]"}},
            {"yaw", &s.yaw}, {"battery", &s.battery}, {"acks", &s.acks}, {"vehicle", &s.vehicle},
            {"type", &s.type}, {"autopilot", &s.autopilot},
            {"location", Numbers{s.location.data(), 3, "[x, y, z]"}},
            {"home", Numbers{s.home.data(), 3, "[x, y, z]"}}, {"status_text", &s.status_text},
            {"battery_failsafe", &s.battery_failsafe},
            {"mission", Wholes{s.mission, 2, "[current, total]"}},
            {"fence_breached", &s.fence_breached}, {"failsafe", &s.failsafe}};
  }
  // Other keys of a script's entry (`t`, ...) are not part of what the automaton sees.
  static bool extra(MavlinkSnap&, const std::string&, const json::Value&, int, const playback::Inputs&) {
    return true;
  }
};

class Mavlink : public Driver<MavlinkSnap>, public Feed {
 public:
  static constexpr const char* kDefaultUrl = "udpin:127.0.0.1:14550";
  static constexpr double kLinkTimeoutS = 2.0;   // no heartbeat for that long: link lost
  static constexpr double kAckTimeoutS = 3.0;    // no COMMAND_ACK by then: failed (resent halfway)
  static constexpr double kGcsHeartbeatS = 1.0;  // our own heartbeat, so the vehicle sees a GCS
  static constexpr int kPollMs = 50;             // longest wait of the reader
  static constexpr double kDatagramWaitS = 10.0;  // lockstep: the simulator's datagrams are that late at most
  static constexpr double kFastRateHz = 20.0;    // position, velocity, attitude (option `rate`)
  static constexpr double kSlowRateHz = 2.0;     // battery, GPS, EKF status
  static constexpr double kHomeRateHz = 1.0;     // HOME_POSITION
  static constexpr size_t kDuplicateWindow = 255;  // frames remembered per source
  static constexpr double kSilenceS = 0.5;       // a source silent that long is a new one

  Mavlink(const std::string& name, const std::string& url,
          const std::map<std::string, std::string>& options);
  ~Mavlink() override;

  Mavlink(const Mavlink&) = delete;
  Mavlink& operator=(const Mavlink&) = delete;

  const std::string& name() const { return Driver::name(); }
  const std::string& url() const { return Driver::url(); }

  // -- state: the snapshot of the instant (never waits on the network) ----------------
  /// A heartbeat from the vehicle within the last 2 s.
  bool connected() const { return snap("connected", "heartbeat_age").heartbeat_age < kLinkTimeoutS; }

  /// Seconds since the vehicle's last heartbeat; +inf before the first.
  double heartbeat_age() const { return snap("heartbeat_age").heartbeat_age; }

  /// The vehicle would accept GUIDED: connected, a 3D GPS fix, an absolute EKF position
  /// (while disarmed a predicted one will do; once armed not in constant-position mode).
  bool ready() const { return snap("ready").ready; }

  /// The vehicle's last heartbeat says its motors are armed.
  bool armed() const { return snap("armed").armed; }

  /// The flight mode's name (GUIDED, LAND, RTL, ...; PX4's names on PX4); "" before the
  /// first heartbeat.
  std::string mode() const { return snap("mode").mode; }

  /// (north, east, down) in m from the EKF origin (LOCAL_POSITION_NED); NaN before any.
  Eigen::Vector3d position() const { return snap("position").position; }

  /// m above home (GLOBAL_POSITION_INT.relative_alt, else -down); NaN before any.
  double altitude() const { return snap("altitude").altitude; }

  /// (vn, ve, vd) in m/s (LOCAL_POSITION_NED); NaN before any.
  Eigen::Vector3d velocity() const { return snap("velocity").velocity; }

  /// Heading in rad (ATTITUDE), 0 north, positive clockwise; NaN before any.
  double yaw() const { return snap("yaw").yaw; }

  /// Battery remaining in percent (SYS_STATUS); -1 when unknown.
  int battery() const { return static_cast<int>(snap("battery").battery); }

  /// (lat, lon) in degrees and m above home (GLOBAL_POSITION_INT); NaN before a GPS fix.
  Eigen::Vector3d location() const { return snap("location").location; }

  /// Home: (lat, lon) in degrees and m above mean sea level (HOME_POSITION); NaN before.
  Eigen::Vector3d home() const { return snap("home").home; }

  /// m from the vehicle to a local point (m from the EKF origin); with `alt` (m above
  /// home) in 3-D, else (NaN) horizontally. NaN before a position.
  double distance_to(double north, double east, double alt = kNaN) const;

  /// m from the vehicle to a point by latitude and longitude (degrees); with `alt` (m
  /// above home) in 3-D, else (NaN) horizontally. NaN before a GPS fix. A latitude or
  /// longitude out of range throws std::invalid_argument.
  double distance_to_location(double lat, double lon, double alt = kNaN) const;

  /// Within `tolerance` m (1 by default) of a local point, in 3-D.
  bool reached(double north, double east, double alt, double tolerance = 1.0) const;

  /// Within `tolerance` m (1 by default) of a point by latitude, longitude and altitude
  /// above home, in 3-D.
  bool reached_location(double lat, double lon, double alt, double tolerance = 1.0) const;

  /// The autopilot's latest STATUSTEXT (chunks joined); "" before any.
  std::string status_text() const { return snap("status_text").status_text; }

  /// The battery's failsafe level (BATTERY_STATUS.charge_state): "" (none), low,
  /// critical, emergency, failed, unhealthy.
  std::string battery_failsafe() const { return snap("battery_failsafe").battery_failsafe; }

  /// (index of the point being flown to, number of points) of the mission uploaded;
  /// (n, n) once its last point is reached (MISSION_CURRENT, MISSION_ITEM_REACHED).
  std::pair<int, int> mission_progress() const {
    const long long* m = snap("mission_progress", "mission").mission;
    return {static_cast<int>(m[0]), static_cast<int>(m[1])};
  }

  /// The vehicle says it is outside its fence (FENCE_STATUS).
  bool fence_breached() const { return snap("fence_breached").fence_breached; }

  /// A failsafe the driver meets, for the model to react to: "link_lost" (no heartbeat
  /// for 2 s), "offboard_lost" (PX4 left OFFBOARD by itself; until the model asks for a
  /// mode, a landing or RTL), "fence" (breached), "battery"; "" when none.
  std::string failsafe() const { return snap("failsafe").failsafe; }

  /// The last outcome of a command (arm, disarm, takeoff, land, rtl, set_mode,
  /// upload_mission, upload_fence, enable_fence):
  /// accepted, denied, temporarily_rejected, unsupported, failed, cancelled,
  /// pending, timeout, not_sent; "" when never sent.
  std::string last_ack(const std::string& command) const;

  // -- Source: the base takes, records and plays back the snapshot ----------------------
  std::string snapshot_schema() const override { return std::string(); }  // the built-in one

  // -- simclock::Synced (joined through the base): lockstep with `hfsmc sim` (--clock sim)
  long long lockstep_sent() const override { return sent_; }
  std::string lockstep_sync(long long t_us, const simclock::Step& step) override;

  // -- commands (send and return; true when sent, i.e. a vehicle is known) ---------
  /// Ask for a flight mode by name (MAV_CMD_DO_SET_MODE with the custom mode; on PX4,
  /// GUIDED is OFFBOARD through the setpoint stream, px4.hpp).
  /// A name the autopilot lacks throws std::invalid_argument (Python: ValueError).
  bool set_mode(const std::string& name);

  /// Arm the motors (MAV_CMD_COMPONENT_ARM_DISARM 1).
  bool arm();

  /// Disarm the motors (MAV_CMD_COMPONENT_ARM_DISARM 0; the vehicle refuses in flight).
  bool disarm();

  /// Climb to `alt` m above home (MAV_CMD_NAV_TAKEOFF; GUIDED and armed).
  bool takeoff(double alt);

  /// Land where the vehicle is (MAV_CMD_NAV_LAND: LAND mode).
  bool land();

  /// Return to launch and land there (MAV_CMD_NAV_RETURN_TO_LAUNCH: RTL mode); with
  /// `alt` (not NaN), at that altitude above home (RTL_ALT, PX4: RTL_RETURN_ALT, set first).
  bool rtl(double alt = kNaN);

  /// Stop where the vehicle is: a zero velocity target (GUIDED).
  bool hold();

  /// Velocity target in the body frame: m/s forward, right, down; rad/s clockwise.
  /// ArduPilot stops the vehicle when no new target comes for 3 s.
  bool set_velocity(double vx, double vy, double vz, double yaw_rate);

  /// Position target in m from the EKF origin (MAV_FRAME_LOCAL_NED, down = -alt); with
  /// `heading` (rad, 0 north, clockwise; NaN: none) the vehicle faces it.
  /// `goto` in Python; a C++ keyword, hence the underscore (recorded as `goto`).
  bool go_to(double north, double east, double alt, double heading = kNaN);

  /// Position target by latitude and longitude (degrees) and m above home
  /// (SET_POSITION_TARGET_GLOBAL_INT); with `heading` (rad) the vehicle faces it. A value
  /// out of range throws std::invalid_argument.
  bool goto_location(double lat, double lon, double alt, double heading = kNaN);

  /// Turn to a heading (rad, 0 north, clockwise): on the way to the latest go_to or
  /// goto_location target, else stopped where the vehicle is (a velocity target ends).
  bool set_yaw(double heading);

  /// Upload a mission (MISSION_ITEM_INT protocol): points {lat, lon, alt above home} or
  /// {lat, lon, alt, heading in rad}, then `end` (hold, land, rtl); its outcome is
  /// last_ack("upload_mission"). A bad point or end throws std::invalid_argument.
  bool upload_mission(const std::vector<std::vector<double>>& points, const std::string& end = "hold");

  /// Upload an inclusion polygon of {lat, lon} vertices (3 at least; none clears the
  /// fence); its outcome is last_ack("upload_fence").
  bool upload_fence(const std::vector<std::vector<double>>& vertices);

  /// Turn the fence on or off (ArduPilot: DO_FENCE_ENABLE; PX4: on once uploaded).
  bool enable_fence(bool on = true);

  /// Stop the reader and close the socket (also done by the destructor).
  void close();

 private:
  using mavlink_message = ::__mavlink_message;
  using Snap = MavlinkSnap;
  // -- for the monitor's viewers (Feed: private here, called through the base) -------
  const char* feed_kind() const override { return "vehicle"; }
  std::string feed_name() const override { return name(); }
  /// A `vehicle` message (schemas/monitor.md) from the state at hand: no request is sent.
  std::string feed_message(long long t_ms) override;

  using Clock = std::chrono::steady_clock;
  static constexpr double kInf = MavlinkSnap::kInf;
  static constexpr double kNaN = MavlinkSnap::kNaN;
  // SET_POSITION_TARGET_LOCAL_NED.type_mask: a set bit means "ignore that field".
  static constexpr uint16_t kIgnorePosition = 0b0000'0000'0111;
  static constexpr uint16_t kIgnoreVelocity = 0b0000'0011'1000;
  static constexpr uint16_t kIgnoreAcceleration = 0b0001'1100'0000;
  static constexpr uint16_t kIgnoreYaw = 0b0100'0000'0000;
  static constexpr uint16_t kIgnoreYawRate = 0b1000'0000'0000;
  static constexpr uint16_t kVelocityMask = kIgnorePosition | kIgnoreAcceleration | kIgnoreYaw;
  static constexpr uint16_t kPositionMask =
      kIgnoreVelocity | kIgnoreAcceleration | kIgnoreYaw | kIgnoreYawRate;
  static constexpr uint16_t kStopFacingMask = kIgnorePosition | kIgnoreAcceleration | kIgnoreYawRate;
  static constexpr uint8_t kGcsComponent = 190;  // MAV_COMP_ID_MISSIONPLANNER, as mavutil

  struct Pending {  // a command waiting for its COMMAND_ACK
    std::string name;   // the key of last_ack()
    std::string label;  // as logged: `set_mode GUIDED`
    uint16_t command;
    float params[7];
    Clock::time_point deadline;
    Clock::time_point resend_at;
    bool resend;  // false once resent (or in progress)
    bool quiet;   // log only a failure (message rates)
  };

  struct State {  // the latest telemetry, under state_
    bool target_seen = false;
    uint8_t target_system = 0, target_component = 0;
    bool heartbeat_seen = false;
    Clock::time_point heartbeat_at{};
    uint8_t type = 0, autopilot = 0, base_mode = 0;
    uint32_t custom_mode = 0;
    Eigen::Vector3d position{kNaN, kNaN, kNaN};
    Eigen::Vector3d velocity{kNaN, kNaN, kNaN};
    bool relative_alt_seen = false;
    double relative_alt = kNaN;
    double yaw = kNaN;
    int battery = -1;
    int gps_fix = 0;
    uint16_t ekf_flags = 0;
    bool prearm = false;  // PX4: SYS_STATUS says the pre-flight checks pass
    bool home_amsl_seen = false;
    double home_amsl = kNaN;  // m: PX4's take-off wants its altitude AMSL
    Eigen::Vector3d location{kNaN, kNaN, kNaN};  // lat, lon, m above home
    Eigen::Vector3d home{kNaN, kNaN, kNaN};  // lat, lon, m AMSL
    std::string status_text;  // the latest STATUSTEXT, whole
    std::string battery_failsafe;  // BATTERY_STATUS.charge_state's name
    int mission_current = 0, mission_total = 0;  // mission_progress()
    bool fence_breached = false;  // FENCE_STATUS.breach_status
  };

  /// The state at hand, as a snapshot (any thread).
  Snap live_snapshot() const;
  /// Live, when an instant begins: the state at hand.
  void read(Snap& latest) override { latest = live_snapshot(); }
  /// What warning_at_stop() says: the vehicle still armed (then nothing lands it:
  /// --until, an error without on_interrupt...); "" when disarmed.
  std::string stop_warning() const override;

  struct Mode {
    uint32_t number;
    const char* name;
  };
  using ModeTable = std::pair<const Mode*, const Mode*>;

  // -- sending ----------------------------------------------------------------------
  bool target(uint8_t* system, uint8_t* component) const;
  uint8_t vehicle_type() const;

  /// A COMMAND_LONG: sent when a vehicle has been heard (the snapshot says so; the
  /// reader thread's own, `quiet`, ask the state at hand), its outcome awaited.
  bool command(const std::string& name, const std::string& label, uint16_t cmd,
               std::initializer_list<float> params, bool quiet = false);
  /// The sending part of command(), from any thread (the snapshot untouched): false when
  /// no vehicle is known or PX4 is not to be sent it (said why).
  bool send_long(Pending p);
  void send_command(uint8_t system, uint8_t component, const Pending& p, uint8_t confirmation);
  bool target_local(uint8_t frame, uint16_t mask, Eigen::Vector3d pos, Eigen::Vector3d vel,
                    double yaw_rate, double yaw = 0);
  /// SET_POSITION_TARGET_LOCAL_NED, or _GLOBAL_INT for a global target; any thread.
  void send_target(const px4::Target& t);
  // -- the mission API's own (src/hfsmc_mission.cpp) -------------------------------------
  bool go_local(double north, double east, double alt, double heading);
  bool go_global(double lat, double lon, double alt, double heading);
  void send_rtl_altitude(double alt);  // a PARAM_SET of RTL_ALT (PX4: RTL_RETURN_ALT)
  void on_home(const mavlink_message& msg);  // HOME_POSITION, BATTERY_STATUS: under state_
  void on_battery_status(const mavlink_message& msg);
  struct Aim {  // the latest position target (set_yaw keeps it)
    int kind = 0;  // 0 none, 1 local (north, east, alt), 2 global (lat, lon, alt)
    double a = 0, b = 0, alt = 0;
  };
  Aim aim_;  // the automaton's thread only
  // -- missions and the fence (src/hfsmc_mission_upload.cpp) ------------------------------
  struct Item {  // one MISSION_ITEM_INT
    uint8_t frame;
    uint16_t command;
    float p[4];
    int32_t x, y;
    float z;
  };
  struct Upload {  // one upload in flight, under link_
    uint8_t kind = 0;  // MAV_MISSION_TYPE: 0 mission, 1 fence
    std::vector<Item> items;
    std::vector<int> users;  // each item's point (-1: none)
    Clock::time_point sent_at{};
    int last = -1;  // the item sent last; -1: MISSION_COUNT
    int retries = 0;
    std::vector<std::pair<double, double>> polygon;
  };
  bool start_upload(const char* name, Upload u);
  ::__mavlink_status* tx_status();  // the sender's state, under link_
  void send_upload(const Upload& u, uint8_t system, uint8_t component);  // under link_: MISSION_COUNT, or the item `last`
  void on_mission_message(const mavlink_message& msg);  // the reader thread
  void upload_tick(Clock::time_point now);
  void fence_check(double lat, double lon);
  std::map<uint8_t, Upload> uploads_;  // under link_
  std::vector<int> users_;  // the mission accepted: each item's point, under link_
  std::vector<std::pair<double, double>> fence_;  // the fence accepted, under link_
  bool fence_on_ = false;  // under link_
  void send(const mavlink_message& msg);  // under link_
  void request_rates();

  // -- the reader thread -------------------------------------------------------------
  void run();
  /// Handle every datagram waiting (at most 1000, so a flood cannot starve the
  /// deadlines); bytes that are no MAVLink frame are dropped, never raised.
  void drain();
  /// A copy of one of the last kDuplicateWindow frames of that source (same seq,
  /// message and checksum): a network duplicate, however late. Reader thread only.
  bool duplicate(const mavlink_message& msg);
  void handle(const mavlink_message& msg);
  void on_heartbeat(const mavlink_message& msg);
  /// The oldest command of that id waiting gets the answer (acks come in order).
  void on_ack(const mavlink_message& msg);
  /// Resend a command once halfway to its deadline; give up at the deadline.
  void expire(Clock::time_point now);
  void watch_link();  // the reader thread: the state at hand, not the automaton's snapshot
  void on_statustext(const mavlink_message& msg);

  // -- PX4 (px4.hpp) -------------------------------------------------------------------
  bool px4() const { return px4_.load(); }
  /// GUIDED on PX4: Hold on the ground (armable; targets switch to OFFBOARD once their
  /// stream runs), in the air a stream holding where the vehicle is, then OFFBOARD.
  bool px4_mode(const std::string& name, uint32_t number);
  /// A command as PX4 wants it (take-off altitude AMSL); the stream stops for a landing,
  /// RTL or a disarm. False: not to be sent (said why).
  bool px4_command(Pending& p);
  /// A second answer (PX4 v1.16 answers DO_SET_MODE at once, then for real): the last
  /// answer counts. Under link_; returns the line to say, or "".
  std::string late_ack(uint16_t command, uint8_t result);
  double now_s() const;  // now() in seconds as Python's driver counts them

  // -- opening -------------------------------------------------------------------------
  /// Open the socket the URL names; "" or why not.
  std::string open_socket();

  // -- helpers -----------------------------------------------------------------------
  /// Option `key` as a positive number, else (said) `fallback`.
  double positive_option(const std::string& key, double fallback) const;
  static ModeTable modes(uint8_t type);
  static std::string mode_name(uint8_t type, uint32_t custom);
  static std::string result_name(uint8_t result);
  static std::string strip(const std::string& s);
  static std::string upper(std::string s);
  static std::string fmt(double x);  // Python's `{x:g}`
  static double seconds(Clock::duration d) { return std::chrono::duration<double>(d).count(); }
  static Clock::duration duration(double s) {
    return std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(s));
  }

  simclock::Client* sim_ = nullptr;  // --clock sim: no reader thread, simulated time
  long long sent_ = 0, received_ = 0;  // datagrams, for the lockstep
  Clock::time_point next_heartbeat_{};
  bool heartbeat_sent_ = false;
  Clock::time_point now() const;  // the simulated time in lockstep, else the steady clock
  void timed(Clock::time_point now);
  const Clock::time_point start_;
  std::string autopilot_ = "auto";  // option `autopilot`: auto, ardupilot or px4
  std::atomic<bool> px4_{false};  // PX4 (the option, else the first heartbeat)
  std::unique_ptr<px4::Offboard> offboard_;
  px4::Texts texts_;  // the reader's own
  struct Answered {  // the last answer to a command id, for a second one (PX4)
    std::string name, label;
    bool quiet;
    Clock::time_point until;
  };
  double takeoff_alt_ = 0;  // the last takeoff()'s altitude, as given (PX4 adds home AMSL)
  double rate_ = kFastRateHz;
  double ack_timeout_ = kAckTimeoutS;
  uint8_t sysid_ = 255;
  int fd_ = -1;
  bool listening_ = false;  // udpin: the peer is whoever speaks MAVLink to us

  mutable std::mutex state_;
  State s_;

  mutable std::mutex link_;
  struct Wire;  // the peer's address and MAVLink's parser and sender states
  std::unique_ptr<Wire> wire_;
  bool peer_known_ = false;
  std::vector<Pending> pending_;
  std::map<std::string, std::string> acks_;
  std::map<uint16_t, Answered> answered_;

  // The reader thread's own.
  std::vector<uint8_t> rx_buf_ = std::vector<uint8_t>(65536);
  bool lost_ = false;  // said on stderr that the link is lost
  struct Recent {  // the last frames of one source, as (seq, msgid, checksum)
    bool any = false;
    Clock::time_point at{};
    std::deque<uint64_t> order;
    std::map<uint64_t, int> count;
  };
  std::map<uint16_t, Recent> recent_;
};

}  // namespace hfsmc
