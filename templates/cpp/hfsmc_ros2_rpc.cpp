// hfsmc: ROS 2 action and service clients (hfsmc/ros2_rpc.hpp, docs/ros2-cpp.md), the twin
// of templates/python/hfsmc_ros2_rpc.py: the same statuses at the same moments.
#include "hfsmc/ros2_rpc.hpp"

#include <cstdio>
#include <cstring>
#include <random>
#include <stdexcept>
#include <utility>

#include <dds/dds.h>

#include "hfsmc/base64.hpp"
#include "hfsmc/cdr.hpp"
#include "hfsmc/json.hpp"
#include "hfsmc/record.hpp"
#include "hfsmc/ros2.hpp"
#include "hfsmc/ros2_wire.hpp"

namespace hfsmc {
namespace ros2 {
namespace rpc {

namespace {

const char* const kGoalStatuses[] = {"none", "pending", "accepted", "executing", "canceling",
                                     "succeeded", "aborted", "canceled", "rejected",
                                     "no_server", "timeout"};
const char* const kCallStatuses[] = {"none", "pending", "done", "no_server", "timeout"};
constexpr std::size_t kHeader = 16;  // the client's id, the sequence number
constexpr int kTakeMax = 64;

/// action_msgs/GoalStatus's values as the status a snippet reads ("" for unknown).
std::string goal_status_of(int v) {
  switch (v) {
    case 1: return "accepted";
    case 2: return "executing";
    case 3: return "canceling";
    case 4: return "succeeded";
    case 5: return "canceled";
    case 6: return "aborted";
    default: return "";
  }
}

bool terminal(const std::string& s) {
  return s == "succeeded" || s == "aborted" || s == "canceled" || s == "rejected" || s == "timeout";
}

std::mt19937_64& rng() {
  static std::mt19937_64 g{std::random_device{}() ^ (static_cast<std::uint64_t>(std::random_device{}()) << 32)};
  return g;
}

dds_qos_t* service_qos(const std::string& userdata, bool transient_local, int depth) {
  dds_qos_t* qos = dds_create_qos();
  dds_qset_reliability(qos, DDS_RELIABILITY_RELIABLE, DDS_MSECS(100));
  dds_qset_durability(qos, transient_local ? DDS_DURABILITY_TRANSIENT_LOCAL : DDS_DURABILITY_VOLATILE);
  dds_qset_history(qos, DDS_HISTORY_KEEP_LAST, depth);
  dds_data_representation_id_t xcdr1 = DDS_DATA_REPRESENTATION_XCDR1;
  dds_qset_data_representation(qos, 1, &xcdr1);
  if (!userdata.empty()) dds_qset_userdata(qos, userdata.data(), userdata.size());
  return qos;
}

dds_entity_t make_topic(dds_entity_t dp, const std::string& name, const std::string& type) {
  struct ddsi_sertype* st = wire::make_sertype(type.c_str());
  dds_entity_t t = dds_create_topic_sertype(dp, name.c_str(), &st, nullptr, nullptr, nullptr);
  if (t < 0) throw StartError("cannot create the DDS topic " + name + " (" + type + "): " + dds_strretcode(t));
  return t;
}

dds_entity_t checked(dds_entity_t e, const std::string& what) {
  if (e < 0) throw StartError("cannot create the DDS " + what + ": " + dds_strretcode(e));
  return e;
}

/// Every sample a reader holds, as CDR bytes (the padding removed).
std::vector<Bytes> take_all(dds_entity_t reader) {
  std::vector<Bytes> out;
  wire::Raw raw;
  void* samples[1] = {&raw};
  dds_sample_info_t info;
  for (int n = 0; n < kTakeMax && dds_take(reader, samples, &info, 1, 1) > 0; ++n)
    if (info.valid_data) out.push_back(std::move(raw.bytes));
  return out;
}

/// One side of a service (a client: writes requests, reads replies).
struct Endpoint {
  dds_entity_t writer = 0, reader = 0;
  std::uint64_t ident = rng()();  // the id this client's requests carry
  long long seq = 0;

  Endpoint(dds_entity_t dp, const std::string& service, const std::string& req_dds,
           const std::string& resp_dds, std::vector<dds_entity_t>& readers,
           std::vector<dds_entity_t>& writers) {
    char tag[40];
    std::snprintf(tag, sizeof tag, "clientid=%016llx;", static_cast<unsigned long long>(ident));
    dds_qos_t* qos = service_qos(tag, false, 10);
    writer = checked(dds_create_writer(dp, make_topic(dp, "rq" + service + "Request", req_dds), qos, nullptr),
                     "writer of " + service);
    reader = checked(dds_create_reader(dp, make_topic(dp, "rr" + service + "Reply", resp_dds), qos, nullptr),
                     "reader of " + service);
    dds_delete_qos(qos);
    readers.push_back(reader);
    writers.push_back(writer);
  }
  bool matched() const {
    dds_publication_matched_status_t p;
    dds_subscription_matched_status_t s;
    return dds_get_publication_matched_status(writer, &p) == DDS_RETCODE_OK && p.current_count > 0 &&
           dds_get_subscription_matched_status(reader, &s) == DDS_RETCODE_OK && s.current_count > 0;
  }
  /// A request (the message's CDR with its encapsulation); its sequence number.
  long long send(const Bytes& msg) {
    ++seq;
    wire::Raw raw;
    raw.bytes.assign(msg.begin(), msg.begin() + 4);
    raw.bytes.resize(4 + kHeader);
    std::memcpy(raw.bytes.data() + 4, &ident, 8);  // little-endian host, as cdr.hpp
    std::memcpy(raw.bytes.data() + 12, &seq, 8);
    raw.bytes.insert(raw.bytes.end(), msg.begin() + 4, msg.end());
    dds_write(writer, &raw);
    return seq;
  }
  /// The replies to this client since the last call: (seq, the message's CDR).
  std::vector<std::pair<long long, Bytes>> take() {
    std::vector<std::pair<long long, Bytes>> out;
    for (Bytes& b : take_all(reader)) {
      if (b.size() < 4 + kHeader) continue;
      std::uint64_t client;
      long long s;
      std::memcpy(&client, b.data() + 4, 8);
      std::memcpy(&s, b.data() + 12, 8);
      if (client != ident) continue;
      Bytes body(b.begin(), b.begin() + 4);
      body.insert(body.end(), b.begin() + 4 + kHeader, b.end());
      out.emplace_back(s, std::move(body));
    }
    return out;
  }
};

Bytes with_goal_id(const std::uint8_t* id, const Bytes* rest, bool stamp) {
  cdr::Writer w;
  w.prims(id, 16);
  if (stamp) {  // GoalInfo's stamp: zero, as rclcpp's cancel of one goal
    w.prim<std::int32_t>(0);
    w.prim<std::uint32_t>(0);
  }
  Bytes out = w.take();
  if (rest != nullptr && rest->size() > 4) out.insert(out.end(), rest->begin() + 4, rest->end());
  return out;
}

}  // namespace

bool running(const std::string& s) {
  return s == "pending" || s == "accepted" || s == "executing" || s == "canceling" || s == "no_server";
}
bool goal_status_known(const std::string& s) {
  for (const char* k : kGoalStatuses)
    if (s == k) return true;
  return false;
}
bool call_status_known(const std::string& s) {
  for (const char* k : kCallStatuses)
    if (s == k) return true;
  return false;
}

// -- the live clients ----------------------------------------------------------------------
class Client {
 public:
  virtual ~Client() = default;
  State state;
  double deadline = 0;  // 0: none
  bool has_waiting = false;
  Bytes waiting;  // a goal or request held until the server is matched
  virtual void poll(double now) = 0;
};

namespace {

class ServiceClient final : public Client {
 public:
  ServiceClient(const Decl& d, dds_entity_t dp, std::vector<dds_entity_t>& r, std::vector<dds_entity_t>& w)
      : d_(d), ep_(dp, d.ros_name, d.dds[0], d.dds[1], r, w) {}
  void call(const Bytes& req, double now) {
    state = State{"pending", {}, {}};
    waiting = req;
    has_waiting = true;
    seq_ = 0;
    deadline = d_.timeout >= 0 ? now + d_.timeout : 0;
  }
  void poll(double now) override {
    for (auto& reply : ep_.take()) {
      if ((state.status == "pending" || state.status == "no_server") && reply.first == seq_ && !has_waiting) {
        try {
          state.a = d_.response(reply.second.data(), reply.second.size());
          state.status = "done";
        } catch (const std::exception& e) {
          std::fprintf(stderr, "hfsmc: ros2: a malformed answer of `%s` dropped (%s)\n", d_.key.c_str(), e.what());
        }
      }
    }
    if (has_waiting) {
      if (ep_.matched()) {
        seq_ = ep_.send(waiting);
        has_waiting = false;
        state.status = "pending";
      } else {
        state.status = "no_server";
      }
    }
    if (deadline > 0 && (state.status == "pending" || state.status == "no_server") && now >= deadline) {
      state.status = "timeout";
      has_waiting = false;
    }
  }

 private:
  const Decl& d_;
  Endpoint ep_;
  long long seq_ = 0;
};

class ActionClient final : public Client {
 public:
  ActionClient(const Decl& d, dds_entity_t dp, std::vector<dds_entity_t>& r, std::vector<dds_entity_t>& w)
      : d_(d),
        send_(dp, d.ros_name + "/_action/send_goal", d.dds[0], d.dds[1], r, w),
        cancel_(dp, d.ros_name + "/_action/cancel_goal", "action_msgs::srv::dds_::CancelGoal_Request_",
                "action_msgs::srv::dds_::CancelGoal_Response_", r, w),
        result_(dp, d.ros_name + "/_action/get_result", d.dds[2], d.dds[3], r, w) {
    dds_qos_t* fq = service_qos("", false, 10);
    feedback_ = checked(dds_create_reader(dp, make_topic(dp, "rt" + d.ros_name + "/_action/feedback", d.dds[4]),
                                          fq, nullptr), "feedback reader");
    dds_delete_qos(fq);
    dds_qos_t* sq = service_qos("", true, 1);
    status_ = checked(dds_create_reader(dp, make_topic(dp, "rt" + d.ros_name + "/_action/status",
                                                       "action_msgs::msg::dds_::GoalStatusArray_"), sq, nullptr),
                      "status reader");
    dds_delete_qos(sq);
    r.push_back(feedback_);
    r.push_back(status_);
  }

  bool running_now() const { return running(state.status); }

  void send_goal(const Bytes& goal, double now) {
    cancel_current();
    for (auto& b : id_) b = static_cast<std::uint8_t>(rng()());
    id_[6] = static_cast<std::uint8_t>((id_[6] & 0x0F) | 0x40);  // a version 4 UUID
    id_[8] = static_cast<std::uint8_t>((id_[8] & 0x3F) | 0x80);
    waiting = with_goal_id(id_, &goal, false);
    has_waiting = true;
    state = State{"pending", {}, {}};
    accepted_ = false;
    send_seq_ = result_seq_ = 0;
    deadline = d_.timeout >= 0 ? now + d_.timeout : 0;
  }

  /// Ask the server to cancel the running goal; false when none runs.
  bool cancel_current() {
    if (!running_now()) return false;
    if (accepted_ || send_seq_) cancel_.send(with_goal_id(id_, nullptr, true));
    has_waiting = false;
    return true;
  }

  void wait_cancel(double s) { dds_wait_for_acks(cancel_.writer, static_cast<dds_duration_t>(s * 1e9)); }

  void poll(double now) override {
    for (auto& reply : send_.take()) {
      if (reply.first != send_seq_ || (state.status != "pending" && state.status != "no_server")) continue;
      if (reply.second.size() < 5) continue;
      if (reply.second[4] != 0) {
        accepted_ = true;
        state.status = "accepted";
        result_seq_ = result_.send(with_goal_id(id_, nullptr, false));
      } else {
        state.status = "rejected";
      }
    }
    for (auto& reply : result_.take()) {
      if (reply.first != result_seq_ || !running_now()) continue;
      try {
        Decoded got = d_.result_response(reply.second.data(), reply.second.size());
        state.status = goal_status_of(got.status);
        got.status = 0;
        state.b = std::move(got);
        if (!terminal(state.status)) state.status = "aborted";
      } catch (const std::exception& e) {
        std::fprintf(stderr, "hfsmc: ros2: a malformed result of `%s` dropped (%s)\n", d_.key.c_str(), e.what());
      }
    }
    cancel_.take();  // the answer changes nothing: the status topic says it
    feedback();
    statuses();
    if (has_waiting) {
      if (send_.matched() && result_.matched()) {
        send_seq_ = send_.send(waiting);
        has_waiting = false;
        state.status = "pending";
      } else {
        state.status = "no_server";
      }
    } else if (accepted_ && running_now() && !result_.matched()) {
      state.status = "no_server";  // the server went away while the goal ran
      accepted_ = false;
    }
    if (deadline > 0 && running_now() && now >= deadline) {
      cancel_current();
      state.status = "timeout";
    }
  }

 private:
  void feedback() {
    for (Bytes& b : take_all(feedback_)) {
      if (b.size() < 4 + 16 || std::memcmp(b.data() + 4, id_, 16) != 0 || !running_now()) continue;
      Bytes alone(b.begin(), b.begin() + 4);  // the feedback after the goal id (16: aligned)
      alone.insert(alone.end(), b.begin() + 20, b.end());
      try {
        state.a = d_.feedback(alone.data(), alone.size());
      } catch (const std::exception&) {  // a malformed sample: dropped
      }
    }
  }
  void statuses() {
    for (Bytes& b : take_all(status_)) {
      try {
        cdr::Reader r(b.data(), b.size());
        const std::size_t n = r.count(25);
        for (std::size_t k = 0; k < n; ++k) {
          std::uint8_t id[16];
          r.prims(id, 16);
          r.prim<std::int32_t>();
          r.prim<std::uint32_t>();
          const std::string said = goal_status_of(r.prim<std::int8_t>());
          if (std::memcmp(id, id_, 16) != 0) continue;
          // a terminal status waits for the result, which comes with it
          if ((said == "accepted" || said == "executing" || said == "canceling") && accepted_ &&
              (state.status == "accepted" || state.status == "executing" || state.status == "canceling"))
            state.status = said;
        }
      } catch (const std::exception&) {  // a malformed status array: dropped
      }
    }
  }

  const Decl& d_;
  Endpoint send_, cancel_, result_;
  dds_entity_t feedback_ = 0, status_ = 0;
  std::uint8_t id_[16] = {};
  bool accepted_ = false;
  long long send_seq_ = 0, result_seq_ = 0;
};

}  // namespace

// -- Rpcs -----------------------------------------------------------------------------------
Rpcs::Rpcs(std::string iface) : iface_(std::move(iface)) {}
Rpcs::~Rpcs() = default;

void Rpcs::attach(Node& node) {
  node.on_start([this](std::int32_t dp, std::vector<std::int32_t>& readers, std::vector<std::int32_t>& writers) {
    for (const Decl& d : decls_) {
      if (d.action) clients_.push_back(std::make_unique<ActionClient>(d, dp, readers, writers));
      else clients_.push_back(std::make_unique<ServiceClient>(d, dp, readers, writers));
    }
  });
}

void Rpcs::snapshot(double now) {
  snap_.resize(decls_.size());
  for (std::size_t k = 0; k < clients_.size(); ++k) {
    clients_[k]->poll(now);
    snap_[k] = clients_[k]->state;
  }
}

const Decl& Rpcs::find(const std::string& key, bool action, const char* method) const {
  std::string listed;
  for (const Decl& d : decls_) {
    if (d.action != action) continue;
    if (d.key == key) return d;
    listed += (listed.empty() ? "" : ", ") + d.key;
  }
  throw std::invalid_argument("the ros2 interface `" + iface_ + "` has no " + (action ? "action" : "service") +
                              " `" + key + "` (" + method + "; " + (action ? "actions" : "services") + ": " +
                              (listed.empty() ? "none" : listed) + ")");
}

bool Rpcs::send_goal(const Decl& d, const Bytes& goal_cdr, double now) {
  State& s = state(d);
  const bool was = running(s.status);  // as this instant sees it
  s = State{"pending", {}, {}};
  if (!clients_.empty()) {
    auto& c = static_cast<ActionClient&>(*clients_[index(d)]);
    c.send_goal(goal_cdr, now);  // cancels the goal it has running
    c.poll(now);
  }
  return was;
}

void Rpcs::cancel(const Decl& d) {
  if (!clients_.empty()) static_cast<ActionClient&>(*clients_[index(d)]).cancel_current();
}

void Rpcs::call(const Decl& d, const Bytes& request_cdr, double now) {
  state(d) = State{"pending", {}, {}};
  if (!clients_.empty()) {
    auto& c = static_cast<ServiceClient&>(*clients_[index(d)]);
    c.call(request_cdr, now);
    c.poll(now);
  }
}

std::vector<std::string> Rpcs::cancel_running() {
  std::vector<std::string> out;
  for (std::size_t k = 0; k < clients_.size(); ++k) {
    if (!decls_[k].action) continue;
    auto& c = static_cast<ActionClient&>(*clients_[k]);
    if (c.running_now() && c.cancel_current()) {
      c.wait_cancel(1.0);
      out.push_back(decls_[k].key);
    }
  }
  return out;
}

// -- recording ------------------------------------------------------------------------------
std::string Rpcs::config() const {
  std::string acts, srvs;
  for (const Decl& d : decls_) {
    std::string& out = d.action ? acts : srvs;
    out += (out.empty() ? "" : ",") + json_string(d.key) + ":{\"name\":" + json_string(d.ros_name) +
           ",\"type\":" + json_string(d.type) + ",\"timeout\":" +
           (d.timeout < 0 ? std::string("null") : json_number(d.timeout)) + "}";
  }
  return "\"actions\":{" + acts + "},\"services\":{" + srvs + "}";
}

std::string Rpcs::fields() const {
  std::string goals, calls;
  for (std::size_t k = 0; k < decls_.size() && k < snap_.size(); ++k) {
    const Decl& d = decls_[k];
    const State& s = snap_[k];
    std::string entry = "{\"status\":" + json_string(s.status);
    const auto message = [&](const char* field, const Decoded& m) {
      const void*& last = recorded_[d.key + "/" + field];  // null before: as Python's `is not`
      if (last == m.msg.get()) return;
      last = m.msg.get();
      entry += ",\"" + std::string(field) + "\":" + (m.cdr ? "\"" + base64(*m.cdr) + "\"" : std::string("null"));
    };
    if (d.action) {
      message("feedback", s.a);
      message("result", s.b);
    } else {
      message("response", s.a);
    }
    std::string& out = d.action ? goals : calls;
    out += (out.empty() ? "" : ",") + json_string(d.key) + ":" + entry + "}";
  }
  std::string out;
  bool any_action = false, any_service = false;
  for (const Decl& d : decls_) (d.action ? any_action : any_service) = true;
  if (any_action) out += ",\"goals\":{" + goals + "}";
  if (any_service) out += ",\"calls\":{" + calls + "}";
  return out;
}

// -- playback -------------------------------------------------------------------------------
std::vector<Rpcs::Given> Rpcs::convert(const json::Value& table, bool goals, bool recorded,
                                       const std::function<void(const std::string&)>& bad,
                                       std::vector<bool>& named) const {
  std::vector<Given> out;
  const char* key = goals ? "goals" : "calls";
  if (table.kind == json::Value::NUL) return out;
  if (table.kind != json::Value::OBJECT) bad(std::string("`") + key + "` must be a mapping");
  for (const auto& m : table.members) {
    const Decl* d = nullptr;
    std::string listed;
    for (const Decl& x : decls_) {
      if (x.action != goals) continue;
      if (x.key == m.first) d = &x;
      listed += (listed.empty() ? "" : ", ") + x.key;
    }
    if (d == nullptr) {
      if (recorded) continue;
      bad(std::string("no ") + (goals ? "action" : "service") + " `" + m.first + "` (" +
          (listed.empty() ? "none" : listed) + ")");
    }
    named[index(*d)] = true;
    const std::string fields = goals ? "feedback, result" : "response";
    const std::string where = std::string("`") + key + "." + m.first + "`";
    const json::Value* status = m.second.kind == json::Value::OBJECT ? m.second.get("status") : nullptr;
    if (status == nullptr || status->kind != json::Value::STRING ||
        !(goals ? goal_status_known(status->text) : call_status_known(status->text)))
      bad(where + ": {status, " + fields + "} with a status among " +
          (goals ? "none, pending, accepted, executing, canceling, succeeded, aborted, canceled, rejected, "
                   "no_server, timeout" : "none, pending, done, no_server, timeout"));
    Given g;
    g.k = index(*d);
    g.status = status->text;
    for (const auto& f : m.second.members) {
      if (f.first == "status") continue;
      const bool is_a = f.first == (goals ? "feedback" : "response");
      if (!is_a && !(goals && f.first == "result")) bad(where + " has no field `" + f.first + "`");
      (is_a ? g.has_a : g.has_b) = true;
      if (f.second.kind == json::Value::NUL) continue;
      const std::string what = "`" + m.first + "`'s " + f.first;
      Bytes bytes;
      if (f.second.kind != json::Value::STRING) bad(what + " must be base64 text");
      if (!unbase64(f.second.text, bytes)) bad(what + " is not base64");
      const Decode& dec = !goals ? d->response : is_a ? d->feedback : d->result;
      try {
        (is_a ? g.a : g.b) = dec(bytes.data(), bytes.size());
      } catch (const std::exception& e) {
        bad(what + " is no " + d->type + (!goals ? " response" : is_a ? " feedback" : " result") + ": " + e.what());
      }
    }
    out.push_back(std::move(g));
  }
  return out;
}

void Rpcs::apply(const std::vector<Given>& given) {
  fed_.resize(decls_.size());
  for (const Given& g : given) {
    State& s = fed_[g.k];
    s.status = g.status;
    if (g.has_a) s.a = g.a;
    if (g.has_b) s.b = g.b;
  }
}

void Rpcs::fake_snapshot() {
  fed_.resize(decls_.size());
  snap_ = fed_;
}

}  // namespace rpc
}  // namespace ros2
}  // namespace hfsmc
