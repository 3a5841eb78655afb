// hfsmc: the base of a C++ component's `ros2` interface (SPEC 5.2, docs/ros2-cpp.md).
//
// The generated class of each `ros2` interface (include/hfsmc_ros2/NAME.hpp) derives from
// hfsmc::ros2::Interface: it declares its subscriptions and publications with their types,
// and gives one typed query per subscription (`robot.scan()`, a `const T*` of this instant's
// snapshot, nullptr before the first) and one `publish` overload per type published. This
// base holds what does not depend on the types:
//
// - the settings: the model's, under NAME.yaml's (node, namespace, domain, each topic's
//   `topic` and `qos`); a key the file may not change (a type, the distro) or does not know
//   stops the component at start with one line, exit 2;
// - the node (hfsmc/ros2.hpp), started when the interface is made; a StartError (a domain
//   id out of range, no usable network, a name ROS 2 forbids) is one line, exit 2;
// - the snapshot, taken by the engine once per instant (Source): age(), count(),
//   publishers(), subscribers() and the typed queries read it until the next instant;
// - publish(): a command, told to the recording (`/hfsmc/command/NAME`, the message's CDR
//   bytes in base64) and then sent at once;
// - with --record, each topic on a channel of its own (the resolved name, the message's
//   `ros2msg` schema, `cdr` bytes): a subscription's sample when it first enters a snapshot,
//   each publish as sent; the JSON snapshot as Python writes it (schemas/recording.md);
// - with --playback (hfsmc replay, hfsmc test) no node is made: the interface is a fake fed
//   from the script's snapshot entries, each sample decoded from its recorded CDR bytes at
//   start (src/hfsmc_ros2_playback.cpp, the twin of hfsmc_ros2_playback.py), and a publish
//   is recorded but never sent;
// - with --clock sim (the ground robot in lockstep, schemas/lockstep.md "Over ROS 2") the
//   hello names the resolved topics, each `next` says how many samples were published on
//   each topic since connecting, and before an instant the interface waits (bounded) until
//   it holds every sample the simulator's step names;
// - with --monitor, a live interface is a Feed (observer.hpp): its topics' rates, ages,
//   counts and matched endpoints as its node holds them, the odometry's pose, and the laser
//   scans for the viewers that asked (hfsmc/ros2view.hpp, docs/web.md); a fake has none;
// - actions and services (SPEC 5.3): the clients of hfsmc/ros2_rpc.hpp on the node's
//   participant; their statuses, feedback, results and responses are part of the snapshot
//   (recorded as `goals` and `calls`), send_goal, cancel and call are commands; with
//   --playback a scenario's scripted servers answer them (hfsmc/ros2_servers.hpp).
#pragma once

#include <cstdint>
#include <cstdio>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

#include "hfsmc/cdr.hpp"
#include "hfsmc/observer.hpp"
#include "hfsmc/record.hpp"
#include "hfsmc/ros2.hpp"
#include "hfsmc/ros2_rpc.hpp"
#include "hfsmc/ros2_servers.hpp"
#include "hfsmc/ros2view.hpp"
#include "hfsmc/simclock.hpp"

namespace hfsmc {
namespace ros2 {

/// One subscription or publication as the model declares it.
struct TopicDecl {
  const char* key;    // the name snippets use (`scan`)
  const char* topic;  // the ROS name as written (`scan`, `/scan`, `~/x`)
  const char* type;   // `sensor_msgs/msg/LaserScan`
  const char* qos;    // a profile name, or `reliability=..,durability=..,depth=..`
  bool publication;
};

class Interface : public Source, public simclock::Synced, private Feed {
 public:
  using Settings = std::map<std::string, std::string>;

  ~Interface() override;
  Interface(const Interface&) = delete;
  Interface& operator=(const Interface&) = delete;

  const std::string& name() const { return name_; }

  /// Seconds since the latest message of subscription `key` arrived (this instant's
  /// snapshot); +inf before the first.
  double age(const std::string& key) const;
  /// Messages of subscription `key` received since start.
  long count(const std::string& key) const;
  /// Remote writers matched with subscription `key`.
  int publishers(const std::string& key) const;
  /// Remote readers matched with publication `key`.
  int subscribers(const std::string& key) const;
  /// Samples of subscription `key` dropped as malformed.
  long malformed(const std::string& key) const;
  /// The resolved ROS name of a subscription or publication (`/tb2/scan`).
  std::string topic(const std::string& key) const;

  // -- actions and services (SPEC 5.3; the typed ones are the generated class's) ---------
  /// none, pending, accepted, executing, canceling, succeeded, aborted, canceled, rejected,
  /// no_server or timeout: the latest goal of action `name` as of this instant.
  std::string goal_status(const std::string& name) const;
  /// Ask the server to cancel the running goal of `name` (a command); false, and nothing
  /// sent, when no goal runs.
  bool cancel(const std::string& name);
  /// none, pending, done, no_server or timeout: the latest call of service `name`.
  std::string call_status(const std::string& name) const;
  /// At stop: a goal still running is cancelled (recorded as `cancel` "stop"); "".
  std::string stop_goals();

  // -- Source: the snapshot of each instant ----------------------------------------------
  const std::string& source_name() const override { return name_; }
  const char* source_type() const override { return "ros2"; }
  std::string source_config() const override;
  void take_snapshot(long long t_us) override;
  std::string snapshot_fields() const override;
  std::string snapshot_schema() const override;
  void record_raw(Recorder& r, long long t_us) const override;

  // -- Feed: the live views (the monitor's thread, under feeds_mutex()) -----------------
  const char* feed_kind() const override { return "ros2"; }
  std::string feed_name() const override { return name_; }
  std::string feed_message(long long t_ms) override;
  void feed_scans(long long t_ms, std::map<std::string, std::pair<long, std::string>>& scans) override;

  // -- simclock::Synced: lockstep with `hfsmc sim --robot diffdrive` ---------------------
  long long lockstep_sent() const override { return 0; }
  void lockstep_topics(std::vector<std::string>& subscribe,
                       std::vector<std::string>& publish) const override;
  std::string lockstep_started(const std::string& hello) override;
  void lockstep_counts(std::map<std::string, long long>& published) const override;
  std::string lockstep_sync(long long t_us, const simclock::Step& step) override;

 protected:
  /// `distro`: the model's (the generated message types are that distro's); `node`, `ns`,
  /// `domain` (-1: $ROS_DOMAIN_ID, else 0): the model's, which `settings` may change.
  Interface(std::string name, const char* distro, const char* node, const char* ns, int domain,
            std::vector<TopicDecl> topics, const Settings& settings);

  template <class T>
  void subscribe(const char* key) {
    Decl& d = decl(key, false, cdr::Traits<T>::ros_type);
    d.definition = cdr::Traits<T>::definition;
    d.decode = [](const std::uint8_t* data, std::size_t size) -> std::shared_ptr<const void> {
      return std::make_shared<const T>(cdr::deserialize<T>(data, size));
    };
    if (node_) guard([&] { node_->subscribe<T>(d.key, d.topic, d.qos); });
  }
  template <class T>
  void advertise(const char* key) {
    Decl& d = decl(key, true, cdr::Traits<T>::ros_type);
    d.definition = cdr::Traits<T>::definition;
    if (node_) guard([&] { node_->advertise<T>(d.key, d.topic, d.qos); });
  }
  /// After the declarations: the node joins the graph (with --playback: the script is read).
  void start();
  /// `introspection: true` (docs/ros2.md "The automaton on ROS 2"): the generated class of a
  /// model that asks for it gives, before start(), the maker of its observer
  /// (hfsmc/ros2_intro.hpp); start() makes it on a live node unless NAME.yaml turned it off.
  using IntrospectionMaker = std::unique_ptr<Observer> (*)(Node&);
  void introspect(IntrospectionMaker make) { introspect_ = make; }

  /// Declare the action `key` of type A (`nav2_msgs::action::NavigateToPose`), ROS name
  /// `ros_name` (as written), time limit `timeout` s (< 0: none); NAME.yaml may change both.
  template <class A>
  void action(const char* key, const char* ros_name, double timeout) {
    using Impl = typename A::Impl;
    rpc::Decl d = rpc_decl(key, ros_name, timeout, true, A::type_name);
    d.dds = {cdr::Traits<typename Impl::SendGoalService::Request>::dds_type,
             cdr::Traits<typename Impl::SendGoalService::Response>::dds_type,
             cdr::Traits<typename Impl::GetResultService::Request>::dds_type,
             cdr::Traits<typename Impl::GetResultService::Response>::dds_type,
             cdr::Traits<typename Impl::FeedbackMessage>::dds_type};
    d.feedback = decoder<typename A::Feedback>();
    d.result = decoder<typename A::Result>();
    d.blank = blank<typename A::Result>;
    d.result_response = [](const std::uint8_t* p, std::size_t n) {
      auto r = cdr::deserialize<typename Impl::GetResultService::Response>(p, n);
      auto m = std::make_shared<const typename A::Result>(std::move(r.result));
      return rpc::Decoded{m, std::make_shared<const rpc::Bytes>(cdr::serialize(*m)), r.status};
    };
    rpc_.declare(std::move(d));
  }
  /// Declare the service `key` of type S (`std_srvs::srv::Trigger`).
  template <class S>
  void service(const char* key, const char* ros_name, double timeout) {
    rpc::Decl d = rpc_decl(key, ros_name, timeout, false, S::type_name);
    d.dds = {cdr::Traits<typename S::Request>::dds_type, cdr::Traits<typename S::Response>::dds_type};
    d.response = decoder<typename S::Response>();
    d.blank = blank<typename S::Response>;
    rpc_.declare(std::move(d));
  }
  /// Send `goal` to action `name` (a command): a goal still running is cancelled first.
  template <class A>
  void send_goal_as(const std::string& name, const typename A::Goal& goal) {
    send_goal_bytes(rpc_typed(name, true, "send_goal", A::type_name), cdr::serialize(goal));
  }
  template <class A>
  const typename A::Feedback* feedback_as(const std::string& name) const {
    return static_cast<const typename A::Feedback*>(
        rpc_message(rpc_typed(name, true, "feedback", A::type_name), "feedback", true));
  }
  template <class A>
  const typename A::Result* result_as(const std::string& name) const {
    return static_cast<const typename A::Result*>(
        rpc_message(rpc_typed(name, true, "result", A::type_name), "result", false));
  }
  /// Call service `name` with `request` (a command); a call still pending is forgotten.
  template <class S>
  void call_as(const std::string& name, const typename S::Request& request) {
    call_bytes(rpc_typed(name, false, "call", S::type_name), cdr::serialize(request));
  }
  template <class S>
  const typename S::Response* response_as(const std::string& name) const {
    return static_cast<const typename S::Response*>(
        rpc_message(rpc_typed(name, false, "response", S::type_name), "response", true));
  }

  /// The latest message of subscription `key` in this instant's snapshot.
  template <class T>
  const T* latest(const char* key) const {
    if (node_) return node_->get<T>(key);
    evidence_.asked(key, key);
    return static_cast<const T*>(fake_message(key));
  }
  /// Publish `msg` on publication `key`: recorded, then sent (live only).
  template <class T>
  void send(const std::string& key, const T& msg) {
    const Decl& d = published(key, cdr::Traits<T>::ros_type);
    send_bytes(d, cdr::serialize(msg));
  }

 private:
  using Decode = std::function<std::shared_ptr<const void>(const std::uint8_t*, std::size_t)>;
  struct Decl {
    std::string key, topic, type;
    Qos qos;
    bool publication = false;
    const char* definition = "";  // ros2msg, for the recording's channel
    Decode decode;                // a subscription's: CDR bytes to its message
  };
  /// With --playback: what the script gave a subscription so far (hfsmc_ros2_playback.cpp).
  struct Fed {
    long count = 0;
    double age = -1;      // < 0: not given (the time since the latest sample's entry)
    int publishers = -1;  // < 0: not given (1 from the first sample on)
    long dropped = 0;
    std::shared_ptr<const void> msg;
    std::shared_ptr<const std::vector<std::uint8_t>> cdr;
    long long arrived = -1;  // the time of the latest sample's entry, us
  };
  /// What one script entry gives a subscription: the fields it names.
  struct Given {
    std::size_t k = 0;  // the declaration
    bool count = false, age = false, publishers = false, dropped = false, cdr = false;
    Fed values;
  };
  /// One script entry of this interface, converted and checked at start.
  struct FedEntry {
    long long t;
    std::vector<Given> subs;
    std::vector<std::pair<std::size_t, int>> subscribers;  // declaration index, count
    std::vector<rpc::Rpcs::Given> rpcs;                      // goals and calls
    rpc::Holding servers;                                    // a scenario's scripted servers
  };
  /// This instant's snapshot of one declaration (a fake's, or the node's copied).
  struct Snap {
    double age = std::numeric_limits<double>::infinity();
    long count = 0, dropped = 0;
    int matched = 0;
    const void* msg = nullptr;
    std::shared_ptr<const std::vector<std::uint8_t>> cdr;
  };
  template <class F>
  void guard(F&& f) {
    try {
      f();
    } catch (const StartError& e) {
      fail(e.what());
    }
  }
  [[noreturn]] void fail(const std::string& why) const;
  template <class T>
  static rpc::Decode decoder() {
    return [](const std::uint8_t* p, std::size_t n) {
      auto m = std::make_shared<const T>(cdr::deserialize<T>(p, n));
      return rpc::Decoded{m, std::make_shared<const rpc::Bytes>(cdr::serialize(*m)), 0};
    };
  }
  template <class T>
  static rpc::Decoded blank() {
    auto m = std::make_shared<const T>();
    return rpc::Decoded{m, std::make_shared<const rpc::Bytes>(cdr::serialize(*m)), 0};
  }
  rpc::Decl rpc_decl(const char* key, const char* ros_name, double timeout, bool action, const char* type);
  const rpc::Decl& rpc_typed(const std::string& name, bool action, const char* method, const char* type) const;
  const void* rpc_message(const rpc::Decl& d, const char* query, bool first) const;
  void send_goal_bytes(const rpc::Decl& d, const std::vector<std::uint8_t>& cdr);
  void call_bytes(const rpc::Decl& d, const std::vector<std::uint8_t>& cdr);
  void configure(const Settings& settings, const char* distro);
  Decl& decl(const char* key, bool publication, const char* ros_type);
  const Decl& published(const std::string& key, const char* ros_type) const;
  const Decl& subscribed(const std::string& key, const char* method) const;
  void send_bytes(const Decl& d, const std::vector<std::uint8_t>& cdr);
  std::size_t index(const Decl& d) const { return static_cast<std::size_t>(&d - decls_.data()); }
  RawChannel raw_channel(const Decl& d) const;
  // -- the playback fake (hfsmc_ros2_playback.cpp) --------------------------------------
  void read_script();
  FedEntry convert(const playback::Entry& e, std::vector<std::string>& missing) const;
  void fake_snapshot(long long t_us);
  const void* fake_message(const char* key) const;

  std::string name_;
  Options options_;
  std::vector<Decl> decls_;
  std::vector<std::string> settings_qos_;  // per declaration, its QoS as written
  std::vector<std::string> written_;       // per declaration, its topic as written (the settings)
  int domain_given_ = -1;                  // the domain as set (-1: $ROS_DOMAIN_ID), for the recording
  std::unique_ptr<Node> node_;  // null with --playback
  IntrospectionMaker introspect_ = nullptr;  // the model asks for introspection
  std::string introspection_;  // NAME.yaml's `introspection` ("true", "false"), "" when not set
  bool feeding_ = false;        // registered as a Feed (a live node)
  ros2view::Rates rates_;       // the monitor thread's
  simclock::Client* sim_ = nullptr;
  std::map<std::string, long long> sent_;  // per resolved topic, published since connecting
  std::map<std::string, long> base_;       // per subscription, received before the lockstep began
  std::vector<Snap> snap_;                 // per declaration, this instant's
  mutable std::map<std::string, long> recorded_;  // per subscription, the count last recorded
  // --playback
  playback::Inputs* inputs_ = nullptr;
  std::vector<FedEntry> script_;
  std::vector<playback::Entry> marks_;  // per script entry: its time and what it lacks
  std::size_t next_ = 0;
  std::vector<Fed> fed_;                 // per declaration
  std::vector<int> fed_subscribers_;     // per declaration (publications)
  playback::Evidence evidence_;
  // actions and services
  rpc::Rpcs rpc_{name_};
  rpc::Scripted servers_;  // --playback: a scenario's scripted servers
  Settings rpc_settings_;  // NAME.yaml's `actions.*` and `services.*`
  bool stopped_ = false;
};

}  // namespace ros2
}  // namespace hfsmc
