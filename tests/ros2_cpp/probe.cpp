// What a ROS 2 graph tool sees of the network (tests/test_ros2_cpp_dds.py): a plain Cyclone
// DDS 0.10 participant (no ROS conventions of its own) reads the DDS built-in topics and
// prints one line per participant, publication and subscription with their QoS and USER_DATA,
// and the CDR bytes of each ros_discovery_info sample in hex (the test decodes them with
// rosbags). It stops after SECONDS.
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <thread>

#include <dds/dds.h>

#include "hfsmc/ros2_wire.hpp"

static std::string hex(const void* p, std::size_t n) {
  static const char* d = "0123456789abcdef";
  std::string s;
  const auto* b = static_cast<const unsigned char*>(p);
  for (std::size_t i = 0; i < n; ++i) { s += d[b[i] >> 4]; s += d[b[i] & 15]; }
  return s;
}

static std::string userdata(const dds_qos_t* qos) {
  void* v = nullptr;
  size_t n = 0;
  if (!qos || !dds_qget_userdata(qos, &v, &n) || n == 0) return "-";
  std::string s(static_cast<const char*>(v), n);
  dds_free(v);
  return s;
}

static void endpoints(dds_entity_t reader, const char* what) {
  void* samples[64] = {nullptr};
  dds_sample_info_t infos[64];
  int n = dds_take(reader, samples, infos, 64, 64);
  for (int i = 0; i < n; ++i) {
    if (!infos[i].valid_data) continue;
    auto* e = static_cast<dds_builtintopic_endpoint_t*>(samples[i]);
    dds_reliability_kind_t rel = DDS_RELIABILITY_BEST_EFFORT;
    dds_duration_t block;
    dds_durability_kind_t dur = DDS_DURABILITY_VOLATILE;
    dds_history_kind_t hist = DDS_HISTORY_KEEP_LAST;
    int32_t depth = -1;
    dds_qget_reliability(e->qos, &rel, &block);
    dds_qget_durability(e->qos, &dur);
    dds_qget_history(e->qos, &hist, &depth);
    std::printf("%s %s participant=%s topic=%s type=%s reliable=%d transient=%d depth=%d "
                "userdata=%s\n", what, hex(e->key.v, 16).c_str(),
                hex(e->participant_key.v, 16).c_str(), e->topic_name, e->type_name,
                rel == DDS_RELIABILITY_RELIABLE, dur == DDS_DURABILITY_TRANSIENT_LOCAL,
                static_cast<int>(depth), userdata(e->qos).c_str());
  }
  if (n > 0) dds_return_loan(reader, samples, n);
}

int main(int argc, char** argv) {
  if (argc < 3) return 1;
  const dds_domainid_t domain = static_cast<dds_domainid_t>(std::atoi(argv[1]));
  const double seconds = std::atof(argv[2]);
  dds_entity_t dp = dds_create_participant(domain, nullptr, nullptr);
  if (dp < 0) return 2;
  dds_entity_t parts = dds_create_reader(dp, DDS_BUILTIN_TOPIC_DCPSPARTICIPANT, nullptr, nullptr);
  dds_entity_t pubs = dds_create_reader(dp, DDS_BUILTIN_TOPIC_DCPSPUBLICATION, nullptr, nullptr);
  dds_entity_t subs = dds_create_reader(dp, DDS_BUILTIN_TOPIC_DCPSSUBSCRIPTION, nullptr, nullptr);
  struct ddsi_sertype* st =
      hfsmc::ros2::wire::make_sertype("rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_");
  dds_entity_t topic = dds_create_topic_sertype(dp, "ros_discovery_info", &st, nullptr, nullptr,
                                                nullptr);
  dds_qos_t* q = dds_create_qos();
  dds_qset_reliability(q, DDS_RELIABILITY_RELIABLE, DDS_MSECS(100));
  dds_qset_durability(q, DDS_DURABILITY_TRANSIENT_LOCAL);
  dds_qset_history(q, DDS_HISTORY_KEEP_LAST, 1);
  dds_entity_t info = dds_create_reader(dp, topic, q, nullptr);
  dds_delete_qos(q);
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  while (std::chrono::steady_clock::now() < end) {
    void* samples[16] = {nullptr};
    dds_sample_info_t infos[16];
    int n = dds_take(parts, samples, infos, 16, 16);
    for (int i = 0; i < n; ++i) {
      if (!infos[i].valid_data) continue;
      auto* p = static_cast<dds_builtintopic_participant_t*>(samples[i]);
      std::printf("participant %s userdata=%s\n", hex(p->key.v, 16).c_str(),
                  userdata(p->qos).c_str());
    }
    if (n > 0) dds_return_loan(parts, samples, n);
    endpoints(pubs, "publication");
    endpoints(subs, "subscription");
    hfsmc::ros2::wire::Raw raw;
    void* one[1] = {&raw};
    dds_sample_info_t si;
    while (dds_take(info, one, &si, 1, 1) > 0)
      if (si.valid_data) std::printf("discovery %s\n", hex(raw.bytes.data(), raw.bytes.size()).c_str());
    std::fflush(stdout);
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  dds_delete(dp);
  return 0;
}
