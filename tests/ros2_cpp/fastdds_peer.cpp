// The other vendor of the cross test (tests/test_ros2_cpp_dds.py): eProsima Fast DDS 2.9
// (Debian's libfastrtps-dev) on loopback only, as a ROS 2 node on rmw_fastrtps would put it on
// the wire: it publishes sensor_msgs/LaserScan on rt/scan (type
// sensor_msgs::msg::dds_::LaserScan_, CDR written by hfsmc's generated types: the test of
// those against rosbags is test_ros2_cpp_cdr.py), first one malformed sample, then a scan every
// 100 ms (stamp.sec = its number, frame_id "fastdds", ranges {0.5 + n, 2, 3}); it reads
// geometry_msgs/Twist on rt/cmd_vel and prints each. It exits 0 after WANT twists, 3 after
// SECONDS without them. It sends nothing before a line on stdin says the reader on the other
// side has matched it: a sample written before that is lost to a volatile reader, and which
// one is lost would depend on the machine's load.
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <thread>
#include <vector>

#include <fastdds/dds/domain/DomainParticipant.hpp>
#include <fastdds/dds/domain/DomainParticipantFactory.hpp>
#include <fastdds/dds/publisher/DataWriter.hpp>
#include <fastdds/dds/publisher/Publisher.hpp>
#include <fastdds/dds/subscriber/DataReader.hpp>
#include <fastdds/dds/subscriber/SampleInfo.hpp>
#include <fastdds/dds/subscriber/Subscriber.hpp>
#include <fastdds/dds/topic/TopicDataType.hpp>
#include <fastdds/dds/topic/TypeSupport.hpp>
#include <fastdds/rtps/transport/UDPv4TransportDescriptor.h>
#include <fastrtps/utils/IPLocator.h>

#include "geometry_msgs/msg/twist.hpp"
#include "sensor_msgs/msg/laser_scan.hpp"

using namespace eprosima::fastdds::dds;
using eprosima::fastrtps::rtps::SerializedPayload_t;

struct Raw {
  std::vector<std::uint8_t> bytes;  // CDR with its encapsulation header
};

class RawType : public TopicDataType {
 public:
  explicit RawType(const char* name) {
    setName(name);
    m_typeSize = 1 << 16;
    m_isGetKeyDefined = false;
  }
  bool serialize(void* data, SerializedPayload_t* payload) override {
    const auto& b = static_cast<Raw*>(data)->bytes;
    if (b.size() > payload->max_size) return false;
    std::memcpy(payload->data, b.data(), b.size());
    payload->length = static_cast<std::uint32_t>(b.size());
    payload->encapsulation = CDR_LE;
    return true;
  }
  bool deserialize(SerializedPayload_t* payload, void* data) override {
    static_cast<Raw*>(data)->bytes.assign(payload->data, payload->data + payload->length);
    return true;
  }
  std::function<std::uint32_t()> getSerializedSizeProvider(void* data) override {
    return [data] { return static_cast<std::uint32_t>(static_cast<Raw*>(data)->bytes.size()); };
  }
  void* createData() override { return new Raw(); }
  void deleteData(void* data) override { delete static_cast<Raw*>(data); }
  bool getKey(void*, eprosima::fastrtps::rtps::InstanceHandle_t*, bool) override { return false; }
};

int main(int argc, char** argv) {
  if (argc < 4) {
    std::fprintf(stderr, "usage: fastdds_peer DOMAIN SECONDS WANT\n");
    return 1;
  }
  const int domain = std::atoi(argv[1]);
  const double seconds = std::atof(argv[2]);
  const int want = std::atoi(argv[3]);

  DomainParticipantQos pq;
  pq.name("fastdds_peer");
  pq.transport().use_builtin_transports = false;
  auto udp = std::make_shared<eprosima::fastdds::rtps::UDPv4TransportDescriptor>();
  udp->interfaceWhiteList.push_back("127.0.0.1");
  pq.transport().user_transports.push_back(udp);
  for (int i = 0; i < 20; ++i) {  // the discovery ports of participants 0..19 on 127.0.0.1
    eprosima::fastrtps::rtps::Locator_t peer;
    eprosima::fastrtps::rtps::IPLocator::setIPv4(peer, 127, 0, 0, 1);
    peer.port = static_cast<std::uint32_t>(7400 + 250 * domain + 10 + 2 * i);
    pq.wire_protocol().builtin.initialPeersList.push_back(peer);
  }
  DomainParticipant* p = DomainParticipantFactory::get_instance()->create_participant(domain, pq);
  if (!p) return 2;
  TypeSupport scan_type(new RawType("sensor_msgs::msg::dds_::LaserScan_"));
  TypeSupport twist_type(new RawType("geometry_msgs::msg::dds_::Twist_"));
  scan_type.register_type(p);
  twist_type.register_type(p);
  Topic* scan_topic = p->create_topic("rt/scan", scan_type.get_type_name(), TOPIC_QOS_DEFAULT);
  Topic* twist_topic = p->create_topic("rt/cmd_vel", twist_type.get_type_name(), TOPIC_QOS_DEFAULT);
  Publisher* pub = p->create_publisher(PUBLISHER_QOS_DEFAULT);
  Subscriber* sub = p->create_subscriber(SUBSCRIBER_QOS_DEFAULT);
  DataWriterQos wq = DATAWRITER_QOS_DEFAULT;
  wq.reliability().kind = RELIABLE_RELIABILITY_QOS;
  wq.durability().kind = VOLATILE_DURABILITY_QOS;
  wq.history().kind = KEEP_LAST_HISTORY_QOS;
  wq.history().depth = 5;
  DataWriter* writer = pub->create_datawriter(scan_topic, wq);
  DataReaderQos rq = DATAREADER_QOS_DEFAULT;
  rq.reliability().kind = RELIABLE_RELIABILITY_QOS;
  rq.durability().kind = VOLATILE_DURABILITY_QOS;
  rq.history().kind = KEEP_LAST_HISTORY_QOS;
  rq.history().depth = 10;
  DataReader* reader = sub->create_datareader(twist_topic, rq);
  if (!writer || !reader) return 2;

  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  int got = 0;
  int n = 0;
  bool malformed_sent = false;
  char go[16];
  if (std::fgets(go, sizeof go, stdin) == nullptr) return 4;  // the test never said go
  auto last = std::chrono::steady_clock::now() - std::chrono::seconds(1);
  while (std::chrono::steady_clock::now() < end && got < want) {
    PublicationMatchedStatus st;
    writer->get_publication_matched_status(st);
    if (st.current_count > 0 && std::chrono::steady_clock::now() - last > std::chrono::milliseconds(100)) {
      last = std::chrono::steady_clock::now();
      Raw raw;
      if (!malformed_sent) {
        raw.bytes = {0x00, 0x01, 0x00, 0x00, 0x07, 0x00, 0x00};  // a LaserScan cut short
        malformed_sent = true;
      } else {
        sensor_msgs::msg::LaserScan scan;
        scan.header.stamp.sec = ++n;
        scan.header.frame_id = "fastdds";
        scan.ranges = {0.5f + static_cast<float>(n), 2.0f, 3.0f};
        raw.bytes = hfsmc::cdr::serialize(scan);
      }
      writer->write(&raw);
    }
    Raw in;
    SampleInfo info;
    while (reader->take_next_sample(&in, &info) == ReturnCode_t::RETCODE_OK) {
      if (!info.valid_data) continue;
      try {
        auto t = hfsmc::cdr::deserialize<geometry_msgs::msg::Twist>(in.bytes.data(), in.bytes.size());
        std::printf("twist x=%g z=%g\n", t.linear.x, t.angular.z);
        ++got;
      } catch (const hfsmc::cdr::Malformed& e) {
        std::printf("bad twist %s\n", e.what());
      }
      std::fflush(stdout);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  p->delete_contained_entities();
  DomainParticipantFactory::get_instance()->delete_participant(p);
  return got >= want ? 0 : 3;
}
