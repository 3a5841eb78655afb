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
// - with --playback (hfsmc replay, hfsmc test) no node is made: nothing arrives, and a
//   publish is recorded but never sent;
// - with --clock sim (the ground robot in lockstep, schemas/lockstep.md "Over ROS 2") the
//   hello names the resolved topics, each `next` says how many samples were published on
//   each topic since connecting, and before an instant the interface waits (bounded) until
//   it holds every sample the simulator's step names.
#pragma once

#include <cstdint>
#include <cstdio>
#include <limits>
#include <map>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "hfsmc/cdr.hpp"
#include "hfsmc/record.hpp"
#include "hfsmc/ros2.hpp"
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

class Interface : public Source, public simclock::Synced {
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

  // -- Source: the snapshot of each instant ----------------------------------------------
  const std::string& source_name() const override { return name_; }
  const char* source_type() const override { return "ros2"; }
  std::string source_config() const override;
  void take_snapshot(long long t_us) override;
  std::string snapshot_fields() const override;
  std::string snapshot_schema() const override;

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
    const Decl& d = decl(key, false, cdr::Traits<T>::ros_type);
    if (node_) guard([&] { node_->subscribe<T>(d.key, d.topic, d.qos); });
  }
  template <class T>
  void advertise(const char* key) {
    const Decl& d = decl(key, true, cdr::Traits<T>::ros_type);
    if (node_) guard([&] { node_->advertise<T>(d.key, d.topic, d.qos); });
  }
  /// After the declarations: the node joins the graph.
  void start();

  /// The latest message of subscription `key` in this instant's snapshot.
  template <class T>
  const T* latest(const char* key) const {
    return node_ ? node_->get<T>(key) : nullptr;
  }
  /// Publish `msg` on publication `key`: recorded, then sent (live only).
  template <class T>
  void send(const std::string& key, const T& msg) {
    const Decl& d = published(key, cdr::Traits<T>::ros_type);
    send_bytes(d, cdr::serialize(msg));
  }

 private:
  struct Decl {
    std::string key, topic, type;
    Qos qos;
    bool publication = false;
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
  void configure(const Settings& settings, const char* distro);
  const Decl& decl(const char* key, bool publication, const char* ros_type) const;
  const Decl& published(const std::string& key, const char* ros_type) const;
  const Decl& subscribed(const std::string& key, const char* method) const;
  void send_bytes(const Decl& d, const std::vector<std::uint8_t>& cdr);

  std::string name_;
  Options options_;
  std::vector<Decl> decls_;
  std::vector<std::string> settings_qos_;  // per declaration, its QoS as written
  std::unique_ptr<Node> node_;  // null with --playback
  simclock::Client* sim_ = nullptr;
  std::map<std::string, long long> sent_;  // per resolved topic, published since connecting
  std::map<std::string, long> base_;       // per subscription, received before the lockstep began
};

}  // namespace ros2
}  // namespace hfsmc
