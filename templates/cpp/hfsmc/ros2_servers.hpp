// hfsmc: action and service servers scripted by an `hfsmc test` scenario (docs/testing.md,
// "Action servers and service responses"), answered by the `ros2` playback fake: the twin of
// hfsmc_ros2_servers.py, with the same script and the same answers.
//
// A scenario's script gives, per action or service, the server that holds from an entry's
// time on (`servers` in a snapshot entry; `null`: none from then on). A goal or a call is
// answered by the server that held when it was sent (one held for want of a server goes to
// the first that holds after, as a live client sends it once the server is matched), from
// the instant after, at the times the server says (relative to the goal or the call), never
// within the instant it was sent (`pending` then):
//
// - an action: `{"accept": bool, "feedback": [[after_us, CDR], ...], "after_us": int|null,
//   "end": "succeeded"|"aborted", "result": CDR|null}`: rejected, or executing with the
//   latest feedback due, then the end with its result (the type's default when none); a
//   cancel from the model makes it `canceled` at the next instant;
// - a service: `{"response": CDR|null, "after_us": int}`: `done` with the response;
// - no server: `no_server` until the model's time limit (`timeout`).
//
// Defined in src/hfsmc_ros2_servers.cpp.
#pragma once

#include <cstddef>
#include <functional>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "hfsmc/jsonvalue.hpp"
#include "hfsmc/ros2_rpc.hpp"

namespace hfsmc {
namespace ros2 {
namespace rpc {

/// One scripted server, decoded at start.
struct Server {
  bool accept = true;
  std::vector<std::pair<long long, Decoded>> feedback;  // (after_us, message), in time order
  long long after_us = -1;  // an action: when it ends (< 0: never); a service: its delay
  std::string end = "succeeded";
  Decoded message;  // the result (an action) or the response (a service); no msg: the default
};
using Held = std::shared_ptr<const Server>;  // null: no server
using Holding = std::vector<std::pair<std::size_t, Held>>;  // per declaration index named

class Scripted {
 public:
  /// One entry's `servers` checked and decoded; `bad(what)` never returns.
  static Holding convert(const json::Value& servers, const std::vector<Decl>& decls,
                         const std::function<void(const std::string&)>& bad);
  /// `every`: a scenario's script that gives no `goals` or `calls` itself: an action or a
  /// service it scripts no server for has none (no_server).
  void start(const std::vector<Decl>& decls, bool every);
  void hold(const Holding& given);
  bool scripted(std::size_t k) const { return every_ || named_[k]; }
  void send(std::size_t k, long long t_us);
  void cancel(std::size_t k, long long t_us);
  /// Declaration k's goal or call as the instant at `now` sees it; false before any was
  /// sent to a scripted server (the script's `goals` and `calls` hold then).
  bool answer(std::size_t k, const Decl& d, long long now, State& out);

 private:
  struct Sent {
    bool any = false;
    long long t0 = 0;         // sent at
    long long at = -1;        // delivered at (< 0: no server yet)
    Held server;
    long long cancelled = -1;
  };
  bool every_ = false;
  std::vector<bool> named_;   // per declaration: a script's entry named its server
  std::vector<Held> held_;    // per declaration: the server that holds now
  std::vector<Sent> sent_;
  std::vector<Decoded> blank_;  // per declaration: the default Result or Response, made once
};

}  // namespace rpc
}  // namespace ros2
}  // namespace hfsmc
