// hfsmc: the base of a C++ component's `ros2` interface (hfsmc/ros2_interface.hpp).
#include "hfsmc/ros2_interface.hpp"

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <set>
#include <thread>
#include <utility>

#include "hfsmc/base64.hpp"
#include "hfsmc/json.hpp"
#include "hfsmc/playback.hpp"
#include "hfsmc/runtime.hpp"

namespace hfsmc {
namespace ros2 {

namespace {

constexpr double kMatchWaitS = 10.0;   // discovery between the simulator's nodes and ours
constexpr double kSampleWaitS = 10.0;  // the samples a step names (schemas/lockstep.md)

// `reliability=best_effort,durability=volatile,depth=5` (the model's three keys) or a
// profile's name; what is not written keeps the default profile's value.
Qos parse_qos(const std::string& text) {
  if (text.find('=') == std::string::npos) return Qos::profile(text);
  Qos q = Qos::profile("default");
  std::size_t start = 0;
  while (start < text.size()) {
    std::size_t end = text.find(',', start);
    if (end == std::string::npos) end = text.size();
    const std::string item = text.substr(start, end - start);
    const std::size_t eq = item.find('=');
    const std::string key = item.substr(0, eq), value = eq == std::string::npos ? "" : item.substr(eq + 1);
    if (key == "reliability" && (value == "reliable" || value == "best_effort")) {
      q.reliable = value == "reliable";
    } else if (key == "durability" && (value == "volatile" || value == "transient_local")) {
      q.transient_local = value == "transient_local";
    } else if (key == "depth" && !value.empty() && value.find_first_not_of("0123456789") == std::string::npos &&
               value.size() < 7 && std::atoi(value.c_str()) >= 1) {
      q.depth = std::atoi(value.c_str());
    } else {
      throw StartError("QoS `" + item + "`: reliability is reliable or best_effort, durability "
                       "volatile or transient_local, depth a whole number from 1");
    }
    start = end + 1;
  }
  return q;
}

}  // namespace

Interface::Interface(std::string name, const char* distro, const char* node, const char* ns, int domain,
                     std::vector<TopicDecl> topics, const Settings& settings)
    : name_(std::move(name)), sim_(simclock::current()) {
  options_.node = node;
  options_.ns = ns;
  options_.domain = domain;
  options_.distro = distro;
  for (const TopicDecl& t : topics) {
    Decl d;
    d.key = t.key;
    d.topic = t.topic;
    d.type = t.type;
    d.publication = t.publication;
    d.qos = Qos::profile("default");
    decls_.push_back(d);
    settings_qos_.push_back(t.qos);
  }
  configure(settings, distro);
  for (const Decl& d : decls_) written_.push_back(d.topic);
  domain_given_ = options_.domain;
  std::set<std::string> seen;
  for (std::size_t k = 0; k < decls_.size(); ++k) {
    Decl& d = decls_[k];
    guard([&] {
      d.qos = parse_qos(settings_qos_[k]);
      d.topic = resolve_topic(d.topic, options_.ns, options_.node);
    });
  }
  guard([&] { options_.domain = domain_id(options_.domain); });
  inputs_ = playback::current();
  if (inputs_ == nullptr) guard([&] { node_ = std::make_unique<Node>(options_); });
  snap_.resize(decls_.size());
  register_source(this);
  if (sim_ != nullptr) sim_->add(this);
}

Interface::~Interface() {
  if (!stopped_ && node_) rpc_.cancel_running();  // a stop that did not ask (not recorded)
  if (feeding_) unregister_feed(this);
  if (sim_ != nullptr && simclock::current() == sim_) sim_->remove(this);
  unregister_source(this);
}

void Interface::fail(const std::string& why) const { throw UsageError(name_ + ": ros2: " + why); }

// NAME.yaml's keys over the model's: node, namespace, domain, each topic's topic and qos.
void Interface::configure(const Settings& settings, const char* distro) {
  const std::string where = "the configuration of interface `" + name_ + "`";
  for (const auto& kv : settings) {
    const std::string& key = kv.first;
    const std::string& value = kv.second;
    if (key == "node") {
      options_.node = value;
    } else if (key == "namespace") {
      options_.ns = value.empty() || value[0] != '/' ? "/" + value : value;
    } else if (key == "domain") {
      char* end = nullptr;
      const long id = std::strtol(value.c_str(), &end, 10);
      if (value.empty() || *end != '\0' || id < 0 || id > 232)
        fail(where + ": domain `" + value + "` is not a ROS 2 domain id (0 to 232)");
      options_.domain = static_cast<int>(id);
    } else if (key == "type") {
      if (value != "ros2") fail(where + ": `type: " + value + "` differs from the model's (ros2): rebuild");
    } else if (key == "distro") {
      if (value != distro)
        fail(where + ": `distro: " + value + "` differs from the model's (" + distro +
             "): the messages are generated for it; change the model and rebuild");
    } else if (key.rfind("subscribe.", 0) == 0 || key.rfind("publish.", 0) == 0) {
      const bool pub = key[0] == 'p';
      const std::string rest = key.substr(pub ? 8 : 10);
      const std::size_t dot = rest.find('.');
      const std::string entry = rest.substr(0, dot), field = dot == std::string::npos ? "" : rest.substr(dot + 1);
      std::size_t k = 0;
      while (k < decls_.size() && !(decls_[k].key == entry && decls_[k].publication == pub)) ++k;
      if (k == decls_.size())
        fail(where + ": `" + (pub ? "publish" : "subscribe") + "` has no `" + entry +
             "` in the model: add it to the model and rebuild");
      if (field == "topic") {
        decls_[k].topic = value;
      } else if (field == "type") {
        if (value != decls_[k].type)
          fail(where + ": `" + key + ": " + value + "` differs from the model's (" + decls_[k].type +
               "): change the model and rebuild");
      } else if (field == "qos") {
        settings_qos_[k] = value;
      } else if (field.rfind("qos.", 0) == 0) {
        std::string& q = settings_qos_[k];
        if (q.find('=') == std::string::npos) q.clear();  // a table replaces a profile
        q += (q.empty() ? "" : ",") + field.substr(4) + "=" + value;
      } else {
        fail(where + ": `" + key + "`: a topic has topic, type and qos");
      }
    } else if (key.rfind("actions.", 0) == 0 || key.rfind("services.", 0) == 0) {
      rpc_settings_[key] = value;  // checked when the class declares its actions (rpc_decl)
    } else if (key == "introspection") {  // may be turned off; on needs its messages generated
      if (value != "true" && value != "false") fail(where + ": `introspection: " + value + "`: true or false");
      introspection_ = value;
    } else if ((key == "url" || key.rfind("options", 0) == 0) && value.empty()) {
      // written empty by older files: nothing to change
    } else {
      fail(where + ": `" + key + "` is not a setting of a ros2 interface (the file may change "
                   "node, namespace, domain and each topic's topic and qos)");
    }
  }
}

Interface::Decl& Interface::decl(const char* key, bool publication, const char* ros_type) {
  for (Decl& d : decls_)
    if (d.key == key && d.publication == publication && d.type == ros_type) return d;
  throw std::logic_error("hfsmc::ros2: `" + std::string(key) + "` is not declared as " + ros_type);
}

const Interface::Decl& Interface::published(const std::string& key, const char* ros_type) const {
  std::string listed;
  for (const Decl& d : decls_) {
    if (!d.publication) continue;
    if (d.key == key) {
      if (d.type != ros_type)
        throw std::invalid_argument(name_ + ".publish: `" + key + "` publishes " + d.type + ", not " + ros_type);
      return d;
    }
    listed += (listed.empty() ? "" : ", ") + d.key;
  }
  throw std::invalid_argument(name_ + ".publish: `" + key + "` is not one of publish: " +
                              (listed.empty() ? "none" : listed));
}

const Interface::Decl& Interface::subscribed(const std::string& key, const char* method) const {
  const bool pub = std::string(method) == "subscribers";
  std::string listed;
  for (const Decl& d : decls_) {
    if (d.publication != pub) continue;
    if (d.key == key) return d;
    listed += (listed.empty() ? "" : ", ") + d.key;
  }
  throw std::invalid_argument(name_ + "." + method + ": `" + key + "` is not one of " +
                              (pub ? "publish" : "subscribe") + ": " + (listed.empty() ? "none" : listed));
}

void Interface::start() {
  for (const auto& kv : rpc_settings_) {  // NAME.yaml's actions and services the model lacks
    const bool act = kv.first[0] == 'a';
    const std::string rest = kv.first.substr(act ? 8 : 9);
    const std::string entry = rest.substr(0, rest.find('.'));
    bool found = false;
    for (const rpc::Decl& d : rpc_.decls()) found = found || (d.key == entry && d.action == act);
    if (!found)
      fail("the configuration of interface `" + name_ + "`: `" + (act ? "actions" : "services") +
           "` has no `" + entry + "` in the model: add it to the model and rebuild");
  }
  if (node_ && !rpc_.empty()) rpc_.attach(*node_);
  if (introspection_ == "true" && introspect_ == nullptr)
    fail("the configuration of interface `" + name_ + "`: `introspection: true`: the model does "
         "not ask for it (its messages are not generated): change the model and rebuild");
  if (node_ && introspect_ != nullptr && introspection_ != "false")
    guard([&] { interface_observers().push_back(introspect_(*node_)); });
  if (node_) {
    guard([&] { node_->start(); });
    register_feed(this);
    feeding_ = true;
  }
  if (inputs_ != nullptr) read_script();
}

// The queries read this instant's snapshot (snap_); with --playback each tells the evidence
// what it reads (the subscription's or publication's name), as the Python fake does.
double Interface::age(const std::string& key) const {
  const Decl& d = subscribed(key, "age");
  evidence_.asked("age", d.key.c_str());
  return snap_[index(d)].age;
}
long Interface::count(const std::string& key) const {
  const Decl& d = subscribed(key, "count");
  evidence_.asked("count", d.key.c_str());
  return snap_[index(d)].count;
}
int Interface::publishers(const std::string& key) const {
  const Decl& d = subscribed(key, "publishers");
  evidence_.asked("publishers", d.key.c_str());
  return snap_[index(d)].matched;
}
int Interface::subscribers(const std::string& key) const {
  const Decl& d = subscribed(key, "subscribers");
  evidence_.asked("subscribers", d.key.c_str());
  return snap_[index(d)].matched;
}
long Interface::malformed(const std::string& key) const {
  const Decl& d = subscribed(key, "malformed");
  evidence_.asked("malformed", d.key.c_str());
  return snap_[index(d)].dropped;
}
std::string Interface::topic(const std::string& key) const {
  for (const Decl& d : decls_)
    if (d.key == key) return d.topic;
  throw std::invalid_argument(name_ + ".topic: no topic `" + key + "`");
}

// -- actions and services ------------------------------------------------------------------
rpc::Decl Interface::rpc_decl(const char* key, const char* ros_name, double timeout, bool action,
                              const char* type) {
  rpc::Decl d;
  d.key = key;
  d.ros_name = ros_name;
  d.type = type;
  d.action = action;
  d.timeout = timeout;
  const std::string where = "the configuration of interface `" + name_ + "`: `";
  const std::string prefix = std::string(action ? "actions." : "services.") + key + ".";
  for (const auto& kv : rpc_settings_) {
    if (kv.first.rfind(prefix, 0) != 0) continue;
    const std::string field = kv.first.substr(prefix.size());
    if (field == "name") {
      d.ros_name = kv.second;
    } else if (field == "timeout") {
      char* end = nullptr;
      const double t = std::strtod(kv.second.c_str(), &end);
      if (kv.second.empty() || kv.second == "null") d.timeout = -1;
      else if (*end != '\0' || !(t > 0) || !std::isfinite(t))
        fail(where + kv.first + ": " + kv.second + "`: a time limit is seconds > 0, or null");
      else d.timeout = t;
    } else if (field == "type") {
      if (kv.second != type)
        fail(where + kv.first + ": " + kv.second + "` differs from the model's (" + type +
             "): change the model and rebuild");
    } else {
      fail(where + kv.first + "`: an action or a service has name, type and timeout");
    }
  }
  guard([&] { d.ros_name = resolve_topic(d.ros_name, options_.ns, options_.node); });
  return d;
}

const rpc::Decl& Interface::rpc_typed(const std::string& name, bool action, const char* method,
                                      const char* type) const {
  const rpc::Decl& d = rpc_.find(name, action, method);
  if (d.type != type)
    throw std::invalid_argument(name_ + "." + method + ": `" + name + "` is a " + d.type + ", not a " + type);
  return d;
}

std::string Interface::goal_status(const std::string& name) const {
  const rpc::Decl& d = rpc_.find(name, true, "goal_status");
  evidence_.asked("goal_status", d.key.c_str());
  return rpc_.state(d).status;
}

std::string Interface::call_status(const std::string& name) const {
  const rpc::Decl& d = rpc_.find(name, false, "call_status");
  evidence_.asked("call_status", d.key.c_str());
  return rpc_.state(d).status;
}

const void* Interface::rpc_message(const rpc::Decl& d, const char* query, bool first) const {
  evidence_.asked(query, d.key.c_str());
  const rpc::State& s = rpc_.state(d);
  return (first ? s.a : s.b).msg.get();
}

void Interface::send_goal_bytes(const rpc::Decl& d, const std::vector<std::uint8_t>& cdr) {
  const double now = std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
  const std::size_t k = static_cast<std::size_t>(&d - rpc_.decls().data());
  if (!node_ && servers_.scripted(k)) servers_.send(k, snapshot_t_);
  if (rpc_.send_goal(d, cdr, now))  // recorded as the instant saw it: a replay tells the same
    sent("cancel", "[" + json_string(d.key) + ",\"replaced\"]");
  sent("send_goal", "[" + json_string(d.key) + "," + json_string(base64(cdr)) + "]");
}

bool Interface::cancel(const std::string& name) {
  const rpc::Decl& d = rpc_.find(name, true, "cancel");
  evidence_.asked("cancel", d.key.c_str());  // it reads the goal's status
  if (!rpc::running(rpc_.state(d).status)) return false;
  rpc_.cancel(d);
  if (!node_) servers_.cancel(static_cast<std::size_t>(&d - rpc_.decls().data()), snapshot_t_);
  sent("cancel", "[" + json_string(d.key) + "]");
  return true;
}

void Interface::call_bytes(const rpc::Decl& d, const std::vector<std::uint8_t>& cdr) {
  const double now = std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
  const std::size_t k = static_cast<std::size_t>(&d - rpc_.decls().data());
  if (!node_ && servers_.scripted(k)) servers_.send(k, snapshot_t_);
  rpc_.call(d, cdr, now);
  sent("call", "[" + json_string(d.key) + "," + json_string(base64(cdr)) + "]");
}

std::string Interface::stop_goals() {
  if (stopped_) return std::string();
  stopped_ = true;
  for (const std::string& key : rpc_.cancel_running()) sent("cancel", "[" + json_string(key) + ",\"stop\"]");
  return std::string();
}

void Interface::send_bytes(const Decl& d, const std::vector<std::uint8_t>& cdr) {
  sent("publish", "[" + json_string(d.key) + "," + json_string(base64(cdr)) + "]");
  if (Recorder* r = recorder()) r->raw(*this, snapshot_t_, raw_channel(d), cdr.data(), cdr.size());
  ++sent_[d.topic];
  if (node_) node_->publish_bytes(d.key, cdr);
}

// -- Feed: the live views (docs/web.md "ROS 2 topics and the map") ---------------------------
// As hfsmc_ros2view.ros2_message: the node, and each topic's rate, age, count and matched
// endpoints as the node holds them now; an odometry subscription's latest pose.
std::string Interface::feed_message(long long t_ms) {
  using ros2view::num;
  const double now =
      std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
  std::string subs, pubs;
  for (const Node::View& v : node_->views()) {
    if (v.key[0] == '~') continue;  // the introspection's own writers (hfsmc/ros2_intro.hpp)
    const double rate = rates_.rate((v.publication ? "p/" : "s/") + v.key, now, v.count);
    std::string e = "{\"name\":" + json_string(v.key) + ",\"topic\":" + json_string(v.topic) +
                    ",\"type\":" + json_string(v.type);
    const std::string r = ",\"rate\":" + (std::isnan(rate) ? std::string("null") : num(rate, 1));
    if (v.publication) {
      e += ",\"count\":" + std::to_string(v.count) + r + ",\"subscribers\":" +
           std::to_string(v.matched) + "}";
      pubs += (pubs.empty() ? "" : ",") + e;
      continue;
    }
    e += r + ",\"age\":" + (v.age < 0 ? std::string("null") : num(v.age)) + ",\"count\":" +
         std::to_string(v.count) + ",\"publishers\":" + std::to_string(v.matched) +
         ",\"dropped\":" + std::to_string(v.dropped);
    ros2view::Pose pose;
    if (v.type == ros2view::ODOMETRY && v.bytes && ros2view::odometry_pose(*v.bytes, pose))
      e += ",\"pose\":" + ros2view::pose_json(pose);
    subs += (subs.empty() ? "" : ",") + e + "}";
  }
  return "{\"type\":\"ros2\",\"t\":" + std::to_string(t_ms) + ",\"name\":" + json_string(name_) +
         ",\"node\":" + json_string(options_.node) + ",\"namespace\":" + json_string(options_.ns) +
         ",\"domain\":" + std::to_string(options_.domain) + ",\"distro\":" +
         json_string(options_.distro) + ",\"subscriptions\":[" + subs + "],\"publications\":[" +
         pubs + "]}";
}

// Each LaserScan subscription's latest scan, made once per new scan, drawn from the pose of
// the first odometry subscription taken back to the scan's stamp.
void Interface::feed_scans(long long t_ms,
                           std::map<std::string, std::pair<long, std::string>>& scans) {
  const std::vector<Node::View> views = node_->views();
  ros2view::Pose odom;
  bool has_odom = false;
  for (const Node::View& v : views) {
    if (!v.publication && v.type == ros2view::ODOMETRY && v.bytes &&
        ros2view::odometry_pose(*v.bytes, odom)) {
      has_odom = true;
      break;
    }
  }
  for (const Node::View& v : views) {
    if (v.publication || v.type != ros2view::LASER_SCAN || !v.bytes) continue;
    const std::string key = name_ + "/" + v.key;
    auto it = scans.find(key);
    if (it != scans.end() && it->second.first == v.count) continue;
    std::string line =
        ros2view::scan_message(name_, v.key, t_ms, *v.bytes, has_odom ? &odom : nullptr);
    if (!line.empty()) scans[key] = {v.count, std::move(line)};
  }
}

// -- Source ---------------------------------------------------------------------------------
// The settings in force, as the Python runtime records them (its `connect` settings): each
// topic as written (unresolved) with its QoS, a profile's name or {reliability, durability,
// depth}; the domain as set (null: $ROS_DOMAIN_ID, else 0); no actions nor services (empty,
// as Python writes a model without them).
std::string Interface::source_config() const {
  std::string subs, pubs;
  for (std::size_t k = 0; k < decls_.size(); ++k) {
    const Decl& d = decls_[k];
    const std::string& q = settings_qos_[k];
    std::string qos = json_string(q);
    if (q.find('=') != std::string::npos) {
      qos.clear();
      std::size_t start = 0;
      while (start < q.size()) {
        std::size_t end = q.find(',', start);
        if (end == std::string::npos) end = q.size();
        const std::string item = q.substr(start, end - start);
        const std::size_t eq = item.find('=');
        const std::string key = item.substr(0, eq), value = item.substr(eq + 1);
        qos += (qos.empty() ? "{" : ",") + json_string(key) + ":" + (key == "depth" ? value : json_string(value));
        start = end + 1;
      }
      qos += "}";
    }
    std::string& out = d.publication ? pubs : subs;
    out += (out.empty() ? "" : ",") + json_string(d.key) + ":{\"topic\":" + json_string(written_[k]) +
           ",\"type\":" + json_string(d.type) + ",\"qos\":" + qos + "}";
  }
  return "{\"type\":\"ros2\",\"url\":null,\"options\":{\"node\":" + json_string(options_.node) +
         ",\"namespace\":" + json_string(options_.ns) + ",\"domain\":" +
         (domain_given_ < 0 ? std::string("null") : std::to_string(domain_given_)) +
         ",\"distro\":" + json_string(options_.distro) + ",\"subscribe\":{" + subs + "},\"publish\":{" + pubs +
         "}," + rpc_.config() + "}}";
}

void Interface::take_snapshot(long long t_us) {
  snapshot_t_ = t_us;
  if (!node_) {
    fake_snapshot(t_us);
    return;
  }
  node_->take_snapshot();
  rpc_.snapshot(std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count());
  for (std::size_t k = 0; k < decls_.size(); ++k) {
    const Decl& d = decls_[k];
    Snap& s = snap_[k];
    if (d.publication) {
      s.matched = node_->subscribers(d.key);
      continue;
    }
    s.age = node_->age(d.key);
    s.count = node_->count(d.key);
    s.dropped = node_->malformed(d.key);
    s.matched = node_->publishers(d.key);
    s.cdr = node_->shared_bytes(d.key);
  }
}

// As the Python runtime writes it (schemas/recording.md): per subscription count, age,
// publishers, dropped; per publication its subscribers. Read from snap_: no query is asked.
std::string Interface::snapshot_fields() const {
  std::string subs, pubs;
  for (std::size_t k = 0; k < decls_.size(); ++k) {
    const Decl& d = decls_[k];
    const Snap& s = snap_[k];
    if (d.publication) {
      pubs += (pubs.empty() ? "" : ",") + json_string(d.key) + ":" + std::to_string(s.matched);
    } else {
      subs += (subs.empty() ? "" : ",") + json_string(d.key) + ":{\"count\":" + std::to_string(s.count) +
              ",\"age\":" + json_number(s.age) + ",\"publishers\":" + std::to_string(s.matched) +
              ",\"dropped\":" + std::to_string(s.dropped) + "}";
    }
  }
  return "\"subscriptions\":{" + subs + "},\"subscribers\":{" + pubs + "}" + rpc_.fields();
}

// The text the Python recorder registers (json.dumps of its schema), so both are alike.
std::string Interface::snapshot_schema() const {
  return "{\"title\": \"What the automaton saw of its ROS 2 topics during one instant\", \"type\":"
         " \"object\", \"properties\": {\"t\": {\"type\": \"integer\"}, \"subscriptions\": {\"type"
         "\": \"object\", \"additionalProperties\": {\"type\": \"object\", \"properties\": {\"coun"
         "t\": {\"type\": \"integer\", \"description\": \"samples arrived since start\"}, \"age\":"
         " {\"type\": [\"number\", \"string\"], \"description\": \"s; inf: none yet\"}, \"publishe"
         "rs\": {\"type\": \"integer\"}, \"dropped\": {\"type\": \"integer\"}}}}, \"subscribers\":"
         " {\"type\": \"object\", \"additionalProperties\": {\"type\": \"integer\"}}, \"goals\": {"
         "\"type\": \"object\", \"description\": \"per action, its latest goal\", \"additionalProp"
         "erties\": {\"type\": \"object\", \"properties\": {\"status\": {\"type\": \"string\"}, \""
         "feedback\": {\"type\": [\"string\", \"null\"], \"contentEncoding\": \"base64\", \"descri"
         "ption\": \"CDR; only in the instant it changed\"}, \"result\": {\"type\": [\"string\", "
         "\"null\"], \"contentEncoding\": \"base64\", \"description\": \"CDR; only in the instant "
         "it changed\"}}}}, \"calls\": {\"type\": \"object\", \"description\": \"per service, its "
         "latest call\", \"additionalProperties\": {\"type\": \"object\", \"properties\": {\"statu"
         "s\": {\"type\": \"string\"}, \"response\": {\"type\": [\"string\", \"null\"], \"contentE"
         "ncoding\": \"base64\", \"description\": \"CDR; only in the instant it changed\"}}}}}}";
}

// A subscription's or publication's channel in the recording: the resolved topic, the
// message's ros2msg definition, cdr bytes, and whose it is (as hfsmc_ros2.py names it).
RawChannel Interface::raw_channel(const Decl& d) const {
  const char* role = d.publication ? "publication" : "subscription";
  return RawChannel{std::string(role) + "/" + d.key, d.topic, d.type, "ros2msg", d.definition, "cdr",
                    {{"hfsmc.interface", name_}, {std::string("hfsmc.") + role, d.key}}};
}

// A subscription's sample is written once, at the instant whose snapshot it first enters.
void Interface::record_raw(Recorder& r, long long t_us) const {
  for (std::size_t k = 0; k < decls_.size(); ++k) {
    const Decl& d = decls_[k];
    const Snap& s = snap_[k];
    if (d.publication || s.cdr == nullptr) continue;
    const auto last = recorded_.find(d.key);
    if (last != recorded_.end() && last->second == s.count) continue;
    recorded_[d.key] = s.count;
    r.raw(*this, t_us, raw_channel(d), s.cdr->data(), s.cdr->size());
  }
}

// -- lockstep (schemas/lockstep.md, "Over ROS 2") ---------------------------------------------
void Interface::lockstep_topics(std::vector<std::string>& subscribe, std::vector<std::string>& publish) const {
  for (const Decl& d : decls_) (d.publication ? publish : subscribe).push_back(d.topic);
}

std::string Interface::lockstep_started(const std::string& hello) {
  if (!node_) return std::string();
  const std::vector<std::string> theirs_out = simclock::names_member(hello, "publish");
  const std::vector<std::string> theirs_in = simclock::names_member(hello, "subscribe");
  const std::set<std::string> out(theirs_out.begin(), theirs_out.end()), in(theirs_in.begin(), theirs_in.end());
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(kMatchWaitS);
  for (;;) {
    node_->take_snapshot();
    std::string missing;
    for (const Decl& d : decls_) {
      const bool matched = d.publication ? (in.count(d.topic) == 0 || node_->subscribers(d.key) > 0)
                                         : (out.count(d.topic) == 0 || node_->publishers(d.key) > 0);
      if (!matched) missing += (missing.empty() ? "" : ", ") + d.topic;
    }
    if (missing.empty()) break;
    if (std::chrono::steady_clock::now() > end) {
      std::fprintf(stderr, "%s: ros2: lockstep: %s did not match the simulator's in %g s (going on)\n",
                   name_.c_str(), missing.c_str(), kMatchWaitS);
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  for (const Decl& d : decls_)
    if (!d.publication) base_[d.key] = node_->count(d.key);
  sent_.clear();
  return std::string();
}

void Interface::lockstep_counts(std::map<std::string, long long>& published) const {
  for (const Decl& d : decls_) {
    if (!d.publication) continue;
    const auto it = sent_.find(d.topic);
    published[d.topic] = it == sent_.end() ? 0 : it->second;
  }
}

std::string Interface::lockstep_sync(long long t_us, const simclock::Step& step) {
  if (!node_) return std::string();
  const std::map<std::string, long long> want = simclock::counts_member(step.line, "topics");
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(kSampleWaitS);
  for (;;) {
    node_->take_snapshot();
    std::string short_of;
    for (const Decl& d : decls_) {
      if (d.publication) continue;
      const auto w = want.find(d.topic);
      const long held = node_->count(d.key) - base_[d.key];
      if (w != want.end() && held < w->second)
        short_of += (short_of.empty() ? "" : ", ") + d.topic + " " + std::to_string(held) + " of " +
                    std::to_string(w->second);
    }
    if (short_of.empty()) return std::string();
    if (std::chrono::steady_clock::now() > end) {
      char text[64];
      std::snprintf(text, sizeof text, " in %g s", kSampleWaitS);
      return name_ + ": ros2: the samples the simulator sent before " + std::to_string(t_us) +
             " us did not all come (" + short_of + ")" + text;
    }
    std::this_thread::sleep_for(std::chrono::microseconds(500));
  }
}

}  // namespace ros2
}  // namespace hfsmc
