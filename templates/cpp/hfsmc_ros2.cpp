// hfsmc: the `ros2` interface's node over Cyclone DDS 0.10 (hfsmc/ros2.hpp, docs/ros2-cpp.md).
#include "hfsmc/ros2.hpp"

#include <atomic>
#include <cctype>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <utility>

#include "hfsmc/ros2_wire.hpp"
#include "rmw_dds_common/msg/participant_entities_info.hpp"

namespace hfsmc {
namespace ros2 {

struct Node::Endpoint {
  std::string key, topic, ros_type, dds_type, type_hash;
  Qos qos;
  bool publication = false;
  Decode decode;
  dds_entity_t entity = 0;
  std::atomic<int> matched{0};
  // The latest sample, written by Cyclone's receive thread.
  std::mutex mu;
  std::shared_ptr<const void> latest;
  std::shared_ptr<const std::vector<std::uint8_t>> latest_bytes;
  Clock::time_point at{};
  long received = 0;
  long bad = 0;
  bool warned = false;
  mutable std::atomic<long> sent{0};  // a publication's samples sent (the monitor's thread reads it)
  // This instant's snapshot: the automaton's thread only.
  std::shared_ptr<const void> snap;
  std::shared_ptr<const std::vector<std::uint8_t>> snap_bytes;
  double snap_age = std::numeric_limits<double>::infinity();
  long snap_count = 0;
  long snap_bad = 0;
  int snap_matched = 0;
};

// -- names, QoS, domain ---------------------------------------------------------------------
Qos Qos::profile(const std::string& name) {
  if (name == "default") return Qos{true, false, 10};
  if (name == "sensor_data") return Qos{false, false, 5};
  if (name == "latched") return Qos{true, true, 1};
  throw StartError("unknown QoS profile '" + name + "' (default, sensor_data, latched)");
}

namespace {

bool token_ok(const std::string& t) {
  if (t.empty() || std::isdigit(static_cast<unsigned char>(t[0]))) return false;
  for (char c : t)
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '_') return false;
  return true;
}

/// Every token of an absolute name is valid ROS 2: no empty token (`//`, a trailing `/`), no
/// token starting with a digit, only letters, digits and `_`.
void check_absolute(const std::string& name, const std::string& what) {
  if (name == "/") return;
  if (name.empty() || name[0] != '/' || name.back() == '/')
    throw StartError(what + " '" + name + "': must start with '/' and not end with '/'");
  std::size_t start = 1;
  while (start <= name.size()) {
    std::size_t end = name.find('/', start);
    if (end == std::string::npos) end = name.size();
    if (!token_ok(name.substr(start, end - start)))
      throw StartError(what + " '" + name + "': each part is letters, digits and '_', "
                       "not starting with a digit, with no '//'");
    if (name.substr(start, end - start).find("__") != std::string::npos)
      throw StartError(what + " '" + name + "': '__' is kept by ROS 2 for itself");
    start = end + 1;
  }
}

std::string join(const std::string& ns, const std::string& rest) {
  return ns == "/" ? "/" + rest : ns + "/" + rest;
}

}  // namespace

std::string resolve_topic(const std::string& name, const std::string& ns, const std::string& node) {
  if (!token_ok(node)) throw StartError("node name '" + node + "': letters, digits and '_', "
                                        "not starting with a digit");
  check_absolute(ns, "namespace");
  if (name.empty()) throw StartError("topic name is empty");
  if (name.find('{') != std::string::npos)
    throw StartError("topic name '" + name + "': substitutions ({...}) are not supported");
  std::string out;
  if (name == "~") {
    out = join(ns, node);
  } else if (name.rfind("~/", 0) == 0) {
    out = join(join(ns, node), name.substr(2));
  } else if (name[0] == '/') {
    out = name;
  } else if (name.find('~') != std::string::npos) {
    throw StartError("topic name '" + name + "': '~' only at its start");
  } else {
    out = join(ns, name);
  }
  check_absolute(out, "topic name");
  if (out.size() + 2 > 255)  // `rt` + the name: DDS topic names ROS 2 accepts
    throw StartError("topic name '" + out + "': longer than ROS 2 allows (253 characters)");
  return out;
}

int domain_id(int configured) {
  long id = configured;
  if (configured < 0) {
    const char* env = std::getenv("ROS_DOMAIN_ID");
    id = 0;
    if (env && *env) {
      char* end = nullptr;
      id = std::strtol(env, &end, 10);
      if (*end) throw StartError(std::string("ROS_DOMAIN_ID '") + env + "' is not a number");
    }
  }
  if (id < 0 || id > 232)
    throw StartError("domain id " + std::to_string(id) + " out of range (0 to 232)");
  return static_cast<int>(id);
}

// -- the node -------------------------------------------------------------------------------
Node::Node(Options options) : options_(std::move(options)) {
  if (options_.distro != "jazzy" && options_.distro != "humble")
    throw StartError("distro '" + options_.distro + "': jazzy or humble");
  if (options_.ns.empty()) options_.ns = "/";
  resolve_topic("~", options_.ns, options_.node);  // checks the node's name and namespace
}

Node::~Node() {
  if (participant_ > 0) dds_delete(participant_);  // its readers and writers with it
  // Cyclone's threads are gone: no callback holds an Endpoint any more.
}

void Node::add(const std::string& key, const std::string& topic, const Qos& qos, bool publication,
               const char* ros_type, const char* dds_type, const char* type_hash, Decode decode) {
  if (participant_) throw std::logic_error("hfsmc::ros2: declare topics before start()");
  if (by_key_.count(key)) throw StartError("'" + key + "' is declared twice");
  auto e = std::make_unique<Endpoint>();
  e->key = key;
  e->topic = resolve_topic(topic, options_.ns, options_.node);
  e->ros_type = ros_type;
  e->dds_type = dds_type;
  e->type_hash = type_hash;
  e->qos = qos;
  e->publication = publication;
  e->decode = std::move(decode);
  for (const auto& other : endpoints_)
    if (other->topic == e->topic && other->ros_type != e->ros_type)
      throw StartError("topic '" + e->topic + "' is used with two types: " + other->ros_type +
                       " ('" + other->key + "') and " + e->ros_type + " ('" + key + "')");
  by_key_[key] = e.get();
  endpoints_.push_back(std::move(e));
}

namespace {

void on_data(dds_entity_t reader, void* arg);

void on_subscription_matched(dds_entity_t, const dds_subscription_matched_status_t st, void* arg) {
  static_cast<std::atomic<int>*>(arg)->store(static_cast<int>(st.current_count));
}

void on_publication_matched(dds_entity_t, const dds_publication_matched_status_t st, void* arg) {
  static_cast<std::atomic<int>*>(arg)->store(static_cast<int>(st.current_count));
}

dds_qos_t* endpoint_qos(const Qos& q, const std::string& type_hash) {
  dds_qos_t* qos = dds_create_qos();
  dds_qset_reliability(qos, q.reliable ? DDS_RELIABILITY_RELIABLE : DDS_RELIABILITY_BEST_EFFORT,
                       DDS_MSECS(100));
  dds_qset_durability(qos, q.transient_local ? DDS_DURABILITY_TRANSIENT_LOCAL
                                             : DDS_DURABILITY_VOLATILE);
  dds_qset_history(qos, DDS_HISTORY_KEEP_LAST, q.depth);
  dds_data_representation_id_t xcdr1 = DDS_DATA_REPRESENTATION_XCDR1;
  dds_qset_data_representation(qos, 1, &xcdr1);
  if (!type_hash.empty()) {  // jazzy: rmw_cyclonedds' USER_DATA of every endpoint
    std::string user = "typehash=" + type_hash + ";";
    dds_qset_userdata(qos, user.data(), user.size());
  }
  return qos;
}

dds_entity_t topic_of(dds_entity_t participant, const std::string& name, const std::string& type) {
  struct ddsi_sertype* st = wire::make_sertype(type.c_str());
  dds_entity_t t = dds_create_topic_sertype(participant, name.c_str(), &st, nullptr, nullptr,
                                            nullptr);
  if (t < 0) {
    throw StartError("cannot create the DDS topic " + name + " (" + type + "): " +
                     dds_strretcode(t));
  }
  return t;
}

}  // namespace

void Node::start() {
  if (participant_) return;
  int domain = domain_id(options_.domain);
  dds_qos_t* pq = dds_create_qos();
  static const char kEnclave[] = "enclave=/;";
  dds_qset_userdata(pq, kEnclave, sizeof kEnclave - 1);
  participant_ = dds_create_participant(static_cast<dds_domainid_t>(domain), pq, nullptr);
  dds_delete_qos(pq);
  if (participant_ < 0) {
    std::string why = dds_strretcode(participant_);
    participant_ = 0;
    throw StartError("cannot start DDS on domain " + std::to_string(domain) + " (" + why +
                     "): no usable network interface, or a bad CYCLONEDDS_URI");
  }
  for (auto& ep : endpoints_) {
    Endpoint* e = ep.get();
    dds_entity_t topic = topic_of(participant_, "rt" + e->topic, e->dds_type);
    dds_qos_t* qos = endpoint_qos(e->qos, options_.distro == "jazzy" ? e->type_hash : "");
    dds_listener_t* l = dds_create_listener(e);
    if (e->publication) {
      dds_lset_publication_matched_arg(l, on_publication_matched, &e->matched, false);
      e->entity = dds_create_writer(participant_, topic, qos, l);
    } else {
      dds_lset_data_available(l, on_data);
      dds_lset_subscription_matched_arg(l, on_subscription_matched, &e->matched, false);
      e->entity = dds_create_reader(participant_, topic, qos, l);
    }
    dds_delete_listener(l);
    dds_delete_qos(qos);
    if (e->entity < 0)
      throw StartError("cannot create the DDS " + std::string(e->publication ? "writer" : "reader") +
                       " of " + e->topic + ": " + dds_strretcode(e->entity));
  }
  for (const Extra& make : extras_) make(participant_, extra_readers_, extra_writers_);
  announce();
}

/// ros_discovery_info: this participant's node and its endpoints, as rmw_cyclonedds sends it
/// (reliable, transient local, keep last 1), so that `ros2 node list` shows the node.
void Node::announce() {
  using Info = rmw_dds_common::msg::ParticipantEntitiesInfo;
  using Tr = cdr::Traits<Info>;
  dds_entity_t topic = topic_of(participant_, "ros_discovery_info", Tr::dds_type);
  dds_qos_t* qos = endpoint_qos(Qos{true, true, 1},
                                options_.distro == "jazzy" ? Tr::type_hash : "");
  discovery_writer_ = dds_create_writer(participant_, topic, qos, nullptr);
  dds_delete_qos(qos);
  if (discovery_writer_ < 0)
    throw StartError(std::string("cannot announce the node: ") + dds_strretcode(discovery_writer_));
  auto gid = [](dds_entity_t entity) {
    rmw_dds_common::msg::Gid g;
    dds_guid_t guid;
    if (dds_get_guid(entity, &guid) == DDS_RETCODE_OK)  // 16 bytes; humble pads to 24 with 0
      std::memcpy(g.data.data(), guid.v, std::min(sizeof guid.v, g.data.size()));
    return g;
  };
  Info info;
  info.gid = gid(participant_);
  rmw_dds_common::msg::NodeEntitiesInfo node;
  node.node_namespace = options_.ns;
  node.node_name = options_.node;
  for (const auto& e : endpoints_)
    (e->publication ? node.writer_gid_seq : node.reader_gid_seq).push_back(gid(e->entity));
  for (dds_entity_t r : extra_readers_) node.reader_gid_seq.push_back(gid(r));
  for (dds_entity_t w : extra_writers_) node.writer_gid_seq.push_back(gid(w));
  info.node_entities_info_seq.push_back(node);
  wire::Raw raw{cdr::serialize(info)};
  dds_write(discovery_writer_, &raw);
}

namespace {

void on_data(dds_entity_t reader, void* arg) {
  auto* e = static_cast<Node::Endpoint*>(arg);
  wire::Raw raw;
  void* samples[1] = {&raw};
  dds_sample_info_t info;
  while (dds_take(reader, samples, &info, 1, 1) > 0) {
    if (!info.valid_data) continue;
    std::shared_ptr<const void> msg;
    try {
      msg = e->decode(raw.bytes.data(), raw.bytes.size());
    } catch (const std::exception& ex) {  // cdr::Malformed, or a size that cannot be allocated
      std::lock_guard<std::mutex> lock(e->mu);
      ++e->bad;
      if (!e->warned) {
        e->warned = true;
        std::fprintf(stderr, "hfsmc: ros2: dropped a malformed %s on %s (%s); counting the "
                     "others silently\n", e->ros_type.c_str(), e->topic.c_str(), ex.what());
      }
      continue;
    }
    auto bytes = std::make_shared<const std::vector<std::uint8_t>>(std::move(raw.bytes));
    raw.bytes = {};
    std::lock_guard<std::mutex> lock(e->mu);
    e->latest = std::move(msg);
    e->latest_bytes = std::move(bytes);
    e->at = Node::Clock::now();
    ++e->received;
  }
}

}  // namespace

// -- the snapshot and the queries --------------------------------------------------------------
void Node::take_snapshot() {
  const Clock::time_point now = Clock::now();
  for (auto& ep : endpoints_) {
    Endpoint& e = *ep;
    e.snap_matched = e.matched.load();
    if (e.publication) continue;
    std::lock_guard<std::mutex> lock(e.mu);
    e.snap = e.latest;
    e.snap_bytes = e.latest_bytes;
    e.snap_count = e.received;
    e.snap_bad = e.bad;
    e.snap_age = e.received ? std::chrono::duration<double>(now - e.at).count()
                            : std::numeric_limits<double>::infinity();
  }
}

const Node::Endpoint& Node::find(const std::string& key) const {
  auto it = by_key_.find(key);
  if (it == by_key_.end()) throw std::out_of_range("hfsmc::ros2: no topic '" + key + "'");
  return *it->second;
}

const Node::Endpoint& Node::sub(const std::string& key, const char* ros_type) const {
  const Endpoint& e = find(key);
  if (e.publication || e.ros_type != ros_type)
    throw std::logic_error("hfsmc::ros2: '" + key + "' is not a subscription of " + ros_type);
  return e;
}

const Node::Endpoint& Node::pub(const std::string& key, const char* ros_type) const {
  const Endpoint& e = find(key);
  if (!e.publication || e.ros_type != ros_type)
    throw std::logic_error("hfsmc::ros2: '" + key + "' does not publish " + ros_type + " but " +
                           (e.publication ? e.ros_type : "is a subscription"));
  return e;
}

const void* Node::snap_message(const Endpoint& e) const { return e.snap.get(); }

const std::vector<std::uint8_t>& Node::bytes(const std::string& key) const {
  static const std::vector<std::uint8_t> none;
  const Endpoint& e = find(key);
  return e.snap_bytes ? *e.snap_bytes : none;
}

std::shared_ptr<const std::vector<std::uint8_t>> Node::shared_bytes(const std::string& key) const {
  return find(key).snap_bytes;
}

double Node::age(const std::string& key) const { return find(key).snap_age; }
long Node::count(const std::string& key) const { return find(key).snap_count; }
long Node::malformed(const std::string& key) const { return find(key).snap_bad; }
int Node::publishers(const std::string& key) const {
  const Endpoint& e = find(key);
  return e.publication ? 0 : e.snap_matched;
}
int Node::subscribers(const std::string& key) const {
  const Endpoint& e = find(key);
  return e.publication ? e.snap_matched : 0;
}
const std::string& Node::topic(const std::string& key) const { return find(key).topic; }

void Node::send(const Endpoint& e, const std::vector<std::uint8_t>& cdr) const {
  if (e.entity <= 0) throw std::logic_error("hfsmc::ros2: publish before start()");
  wire::Raw raw{cdr};
  dds_return_t rc = dds_write(e.entity, &raw);
  ++e.sent;
  if (rc != DDS_RETCODE_OK)
    std::fprintf(stderr, "hfsmc: ros2: %s not sent: %s\n", e.topic.c_str(), dds_strretcode(rc));
}

void Node::publish_bytes(const std::string& key, const std::vector<std::uint8_t>& cdr) {
  const Endpoint& e = find(key);
  if (!e.publication) throw std::logic_error("hfsmc::ros2: '" + key + "' is a subscription");
  send(e, cdr);
}

std::vector<Node::View> Node::views() const {
  const Clock::time_point now = Clock::now();
  std::vector<View> out;
  for (const auto& ep : endpoints_) {
    Endpoint& e = *ep;
    View v;
    v.key = e.key;
    v.topic = e.topic;
    v.type = e.ros_type;
    v.publication = e.publication;
    v.matched = e.matched.load();
    if (e.publication) {
      v.count = e.sent.load();
    } else {
      std::lock_guard<std::mutex> lock(e.mu);
      v.count = e.received;
      v.dropped = e.bad;
      v.bytes = e.latest_bytes;
      if (e.received) v.age = std::chrono::duration<double>(now - e.at).count();
    }
    out.push_back(std::move(v));
  }
  return out;
}

}  // namespace ros2
}  // namespace hfsmc
