// hfsmc: ROS 2 action and service clients of a C++ component's `ros2` interface (SPEC 5.3,
// docs/ros2.md "Services and actions", docs/ros2-cpp.md), the twin of hfsmc_ros2_rpc.py.
//
// rmw_cyclonedds_cpp's request/reply mapping: a service `/ns/reset` is the topics
// `rq/ns/resetRequest` and `rr/ns/resetReply` (reliable, volatile, keep last 10), each sample
// the request header (the client's 8-byte id, a 64-bit sequence number, little endian)
// right after the CDR encapsulation, then the message; a client keeps the replies with its own
// id, and its endpoints carry `clientid=<id>;` in their USER_DATA. An action `/ns/navigate` is
// the services `navigate/_action/send_goal`, `.../cancel_goal`, `.../get_result` and the
// topics `navigate/_action/feedback` and `.../status` (transient local, keep last 1).
//
// This part knows no generated type: it works on CDR bytes, and the generated interface class
// gives it, per action or service, the decoders of its messages (Decode). What it builds
// itself has a fixed layout: a goal request is the goal id (16 bytes) then the goal's CDR
// (16 keeps every alignment), a result request and a cancel are the goal id (and a zero
// stamp), a goal response starts with `accepted`, a status array is read field by field.
//
// Everything runs on the automaton's thread: the clients take what came at the start of each
// instant (Rpcs::snapshot), so statuses change between instants, never inside one. Defined
// in src/hfsmc_ros2_rpc.cpp.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "hfsmc/base64.hpp"
#include "hfsmc/jsonvalue.hpp"

namespace hfsmc {
namespace ros2 {
class Node;

namespace rpc {

using Bytes = std::vector<std::uint8_t>;
using Shared = std::shared_ptr<const Bytes>;

/// A message decoded from CDR, with its own CDR (as the recording keeps it) and, for a
/// result response, the goal's final status (action_msgs/GoalStatus).
struct Decoded {
  std::shared_ptr<const void> msg;
  Shared cdr;
  int status = 0;
};
/// CDR bytes (with the encapsulation) to a Decoded; throws cdr::Malformed.
using Decode = std::function<Decoded(const std::uint8_t*, std::size_t)>;

/// What the generated class tells of one action or service.
struct Decl {
  std::string key;       // the name snippets use
  std::string ros_name;  // as written (NAME.yaml may change it), resolved at start
  std::string type;      // pkg/action/Name or pkg/srv/Name
  bool action = false;
  double timeout = -1;   // s; < 0: none
  // The DDS type names: send_goal request/response, get_result request/response, feedback
  // message (an action); request, response (a service: the first two).
  std::vector<std::string> dds;
  Decode feedback, result, result_response;  // an action's (standalone Feedback, Result)
  Decode response;                           // a service's
  std::function<Decoded()> blank;            // the default Result (an action) or Response
};

/// The latest goal of an action or call of a service, as an instant sees it.
struct State {
  std::string status = "none";
  Decoded a, b;  // an action: its feedback and result; a service: its response (a)
};

bool running(const std::string& goal_status);
bool goal_status_known(const std::string& s);
bool call_status_known(const std::string& s);
using hfsmc::base64;  // hfsmc/base64.hpp: the bytes a recording keeps as text
using hfsmc::unbase64;

class Client;  // one live action or service client (src/hfsmc_ros2_rpc.cpp)

/// The actions and services of one interface: declarations, live clients or the playback's
/// script, this instant's states, and their recording.
class Rpcs {
 public:
  explicit Rpcs(std::string iface);
  ~Rpcs();
  Rpcs(const Rpcs&) = delete;
  Rpcs& operator=(const Rpcs&) = delete;

  void declare(Decl d) { decls_.push_back(std::move(d)); }
  bool empty() const { return decls_.empty(); }
  std::vector<Decl>& decls() { return decls_; }
  const std::vector<Decl>& decls() const { return decls_; }
  /// The clients are made on `node`'s participant when it starts (names already resolved).
  void attach(Node& node);

  /// The start of an instant: what the servers said since (live), the time limits; the
  /// states the queries read until the next instant.
  void snapshot(double now);
  /// The declaration of `key`, an action (or a service); std::invalid_argument listing the
  /// names when there is none.
  const Decl& find(const std::string& key, bool action, const char* method) const;
  State& state(const Decl& d) { return snap_[index(d)]; }
  const State& state(const Decl& d) const { return snap_[index(d)]; }

  // Commands (live: sent now). send_goal returns whether the instant saw a goal running
  // (then the client cancels it: the caller records `cancel` "replaced").
  bool send_goal(const Decl& d, const Bytes& goal_cdr, double now);
  void cancel(const Decl& d);
  void call(const Decl& d, const Bytes& request_cdr, double now);
  /// At stop: each action whose goal still runs is cancelled (the request given a second
  /// to reach the server): their names.
  std::vector<std::string> cancel_running();

  // The recording (as hfsmc_ros2_rpc.py's as_recorded and the settings).
  std::string config() const;  // `"actions":{...},"services":{...}`
  std::string fields() const;  // `,"goals":{...},"calls":{...}`, "" without any

  // The playback: a script's `goals` or `calls` (one entry) checked and decoded, and applied.
  struct Given {
    std::size_t k = 0;
    std::string status;
    bool has_a = false, has_b = false;
    Decoded a, b;
  };
  /// `bad(what)` never returns; names the model lacks are skipped in a recorded script.
  std::vector<Given> convert(const json::Value& table, bool goals, bool recorded,
                             const std::function<void(const std::string&)>& bad,
                             std::vector<bool>& named) const;
  void apply(const std::vector<Given>& given);
  void fake_snapshot();

 private:
  std::size_t index(const Decl& d) const { return static_cast<std::size_t>(&d - decls_.data()); }
  std::string iface_;
  std::vector<Decl> decls_;
  std::vector<std::unique_ptr<Client>> clients_;  // per declaration; live only
  std::vector<State> snap_;                       // per declaration, this instant's
  std::vector<State> fed_;                        // per declaration, the script's so far
  mutable std::map<std::string, const void*> recorded_;  // the messages last recorded
};

}  // namespace rpc
}  // namespace ros2
}  // namespace hfsmc
