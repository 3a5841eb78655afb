// hfsmc: the `ros2` interface of C++ components (docs/ros2.md, docs/ros2-cpp.md): a ROS 2
// node with no ROS 2 installed, over Debian's Eclipse Cyclone DDS 0.10 C API.
//
// The node is a DDS participant with ROS 2's conventions: USER_DATA `enclave=/;`, topics
// `rt/` + the resolved name, types `pkg::msg::dds_::Name_`, plain CDR (XCDR1), and the node
// with its endpoints announced on `ros_discovery_info` in the distro's layout (the Gid is 24
// bytes on humble, 16 on jazzy: the generated rmw_dds_common types carry that), with jazzy's
// `typehash=RIHS01_...;` in each endpoint's USER_DATA. The messages are the generated
// `pkg::msg::Name` types (include/PKG/msg/NAME.hpp), which write their CDR themselves: the
// bytes go through Cyclone as they are (a sertype of raw CDR, as rmw_cyclonedds does for
// serialized messages), so every sample sent is rosbags' bytes of the message, and a sample
// that does not parse as its type is dropped and counted, never a crash.
//
// One snapshot per instant: Cyclone's receive thread decodes each sample into a fresh
// message and keeps the latest per subscription under a mutex; take_snapshot() copies those
// pointers (and the counts of matched endpoints a listener keeps), so get<T>(), age(),
// count(), publishers() and subscribers() read this instant's state until the next one.
// publish() sends at once. Defined in src/hfsmc_ros2.cpp and src/hfsmc_ros2_wire.cpp.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

#include "hfsmc/cdr.hpp"

namespace hfsmc {
namespace ros2 {

/// The interface cannot start (a domain id out of range, no usable network, a bad name):
/// one line for the user, and the component exits 2.
struct StartError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// A ROS 2 QoS profile as the `ros2` interface names them (docs/ros2.md).
struct Qos {
  bool reliable = true;
  bool transient_local = false;
  int depth = 10;
  /// `default` (reliable, volatile, 10), `sensor_data` (best effort, volatile, 5),
  /// `latched` (reliable, transient local, 1); anything else throws StartError.
  static Qos profile(const std::string& name);
};

/// ROS 2's name resolution: a relative `name` against the namespace, `~` and `~/x` against
/// the node, an absolute name as it is. A name ROS 2 forbids throws StartError that says why.
std::string resolve_topic(const std::string& name, const std::string& ns, const std::string& node);

/// The domain id: `configured` when >= 0, else $ROS_DOMAIN_ID, else 0; outside 0..232 (the
/// range ROS 2 accepts on the default ports) throws StartError.
int domain_id(int configured);

struct Options {
  std::string node;        // the node's name
  std::string ns = "/";    // its namespace
  int domain = -1;         // -1: $ROS_DOMAIN_ID, else 0
  std::string distro = "jazzy";  // jazzy or humble
};

class Node {
 public:
  using Clock = std::chrono::steady_clock;
  /// A subscription's or a publication's state, shared with Cyclone's threads.
  struct Endpoint;

  explicit Node(Options options);
  ~Node();
  Node(const Node&) = delete;
  Node& operator=(const Node&) = delete;

  /// Declare a subscription `key` of topic `topic` (a ROS name, resolved here) of type T.
  template <class T>
  void subscribe(const std::string& key, const std::string& topic, const Qos& qos) {
    using Tr = cdr::Traits<T>;
    add(key, topic, qos, false, Tr::ros_type, Tr::dds_type, Tr::type_hash,
        [](const std::uint8_t* data, std::size_t size) -> std::shared_ptr<const void> {
          return std::make_shared<const T>(cdr::deserialize<T>(data, size));
        });
  }
  /// Declare a publication `key` of topic `topic` of type T.
  template <class T>
  void advertise(const std::string& key, const std::string& topic, const Qos& qos) {
    using Tr = cdr::Traits<T>;
    add(key, topic, qos, true, Tr::ros_type, Tr::dds_type, Tr::type_hash, nullptr);
  }

  /// Endpoints others make on this node's participant (the action and service clients,
  /// hfsmc/ros2_rpc.hpp): `make(participant, readers, writers)` runs in start(), before the
  /// node is announced, and the entities it lists are announced as the node's.
  using Extra = std::function<void(std::int32_t, std::vector<std::int32_t>&,
                                   std::vector<std::int32_t>&)>;
  void on_start(Extra make) { extras_.push_back(std::move(make)); }

  /// Create the participant, the readers and writers, and announce the node; StartError
  /// when the domain id or the network is not usable.
  void start();

  /// The snapshot of this instant: every query below reads it until the next call.
  void take_snapshot();

  /// The latest message of subscription `key` as of this instant's snapshot; nullptr before
  /// the first. Stays valid until the next snapshot at least.
  template <class T>
  const T* get(const std::string& key) const {
    const Endpoint& e = sub(key, cdr::Traits<T>::ros_type);
    return static_cast<const T*>(snap_message(e));
  }
  /// Its CDR bytes (for the recording): empty before the first.
  const std::vector<std::uint8_t>& bytes(const std::string& key) const;
  /// The same bytes, shared (null before the first): kept by a recording without a copy.
  std::shared_ptr<const std::vector<std::uint8_t>> shared_bytes(const std::string& key) const;
  double age(const std::string& key) const;          // seconds; +inf before the first
  long count(const std::string& key) const;          // samples received since start
  long malformed(const std::string& key) const;      // samples dropped as malformed
  int publishers(const std::string& key) const;      // matched remote writers
  int subscribers(const std::string& key) const;     // matched remote readers (publication)

  /// Send a message now on publication `key` (a command).
  template <class T>
  void publish(const std::string& key, const T& msg) {
    const Endpoint& e = pub(key, cdr::Traits<T>::ros_type);
    send(e, cdr::serialize(msg));
  }
  /// Send CDR bytes (with their encapsulation header) as they are: a replayed recording.
  void publish_bytes(const std::string& key, const std::vector<std::uint8_t>& cdr);

  /// The resolved ROS name of a subscription or publication (`/tb2/scan`).
  const std::string& topic(const std::string& key) const;
  const Options& options() const { return options_; }

  /// A subscription or publication as the live views show it, read now.
  struct View {
    std::string key, topic, type;
    bool publication = false;
    long count = 0;     // received (a subscription) or published (a publication)
    double age = -1;    // seconds since the latest sample; < 0 before the first
    int matched = 0;    // matched remote writers (a subscription) or readers
    long dropped = 0;   // malformed samples dropped
    std::shared_ptr<const std::vector<std::uint8_t>> bytes;  // the latest sample's
  };
  /// What the live views show (the monitor's thread calls it, after start(); the
  /// instant's snapshot is left alone), in the order declared.
  std::vector<View> views() const;

 private:
  using Decode = std::function<std::shared_ptr<const void>(const std::uint8_t*, std::size_t)>;
  void add(const std::string& key, const std::string& topic, const Qos& qos, bool publication,
           const char* ros_type, const char* dds_type, const char* type_hash, Decode decode);
  const Endpoint& sub(const std::string& key, const char* ros_type) const;
  const Endpoint& pub(const std::string& key, const char* ros_type) const;
  const Endpoint& find(const std::string& key) const;
  const void* snap_message(const Endpoint& e) const;
  void send(const Endpoint& e, const std::vector<std::uint8_t>& cdr) const;
  void announce();

  Options options_;
  std::int32_t participant_ = 0;
  std::int32_t discovery_writer_ = 0;
  std::vector<std::unique_ptr<Endpoint>> endpoints_;  // in the order declared
  std::map<std::string, Endpoint*> by_key_;
  std::vector<Extra> extras_;
  std::vector<std::int32_t> extra_readers_, extra_writers_;
};

}  // namespace ros2
}  // namespace hfsmc
