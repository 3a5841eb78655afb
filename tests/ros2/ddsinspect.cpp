// What a ROS 2 tool on Cyclone DDS 0.10 (ROS 2 Humble's and Jazzy's DDS, Debian's
// cyclonedds-dev) sees of a domain: a plain participant with no ROS conventions of its own
// reads the DDS built-in topics (participants, publications and subscriptions with their
// topic and type names, QoS, data representation and USER_DATA) and the samples of
// ros_discovery_info as CDR bytes (read raw through templates/cpp/hfsmc_ros2_wire.cpp's
// sertype; the tests decode them with rosbags). One JSON object a line on stdout, for
// tests/test_ros2_wire.py (Python components) and tests/test_ros2_cpp_dds.py (C++).
//
// usage: ddsinspect DOMAIN TIMEOUT_S TOPIC...
// Waits until a publication or subscription of each TOPIC is seen (exit 0) or the timeout
// passes (exit 1), reads a second more, then prints every endpoint seen; each
// ros_discovery_info sample is printed as it arrives: {"kind":"discovery","cdr":HEX}. The
// first line names its own participant ({"kind":"self","key":HEX}): its reader of
// ros_discovery_info is no one's under test.
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

#include <dds/dds.h>

#include "hfsmc/ros2_wire.hpp"

namespace {

constexpr int MAXS = 256;

std::string hex(const void* p, std::size_t n) {
  static const char* d = "0123456789abcdef";
  std::string s;
  const auto* b = static_cast<const unsigned char*>(p);
  for (std::size_t i = 0; i < n; ++i) {
    s += d[b[i] >> 4];
    s += d[b[i] & 15];
  }
  return s;
}

std::string userdata(const dds_qos_t* qos) {
  void* v = nullptr;
  std::size_t n = 0;
  std::string s;
  if (qos && dds_qget_userdata(qos, &v, &n) && v) s = hex(v, n);
  dds_free(v);
  return s;
}

void endpoint(const char* kind, const dds_builtintopic_endpoint_t* e) {
  dds_reliability_kind_t rel = DDS_RELIABILITY_BEST_EFFORT;
  dds_duration_t blocking = 0;
  dds_durability_kind_t dur = DDS_DURABILITY_VOLATILE;
  dds_history_kind_t hist = DDS_HISTORY_KEEP_LAST;
  int32_t depth = 0;
  uint32_t nrep = 0;
  dds_data_representation_id_t* reps = nullptr;
  dds_qget_reliability(e->qos, &rel, &blocking);
  dds_qget_durability(e->qos, &dur);
  dds_qget_history(e->qos, &hist, &depth);
  dds_qget_data_representation(e->qos, &nrep, &reps);
  std::string r;
  for (uint32_t i = 0; i < nrep; i++) r += (i ? "," : "") + std::to_string(reps[i]);
  std::printf("{\"kind\":\"%s\",\"key\":\"%s\",\"participant\":\"%s\",\"topic\":\"%s\","
              "\"type\":\"%s\",\"reliable\":%s,\"transient_local\":%s,\"keep_last\":%s,"
              "\"depth\":%d,\"representation\":[%s],\"user_data\":\"%s\"}\n",
              kind, hex(e->key.v, 16).c_str(), hex(e->participant_key.v, 16).c_str(),
              e->topic_name, e->type_name, rel == DDS_RELIABILITY_RELIABLE ? "true" : "false",
              dur == DDS_DURABILITY_TRANSIENT_LOCAL ? "true" : "false",
              hist == DDS_HISTORY_KEEP_LAST ? "true" : "false", static_cast<int>(depth),
              r.c_str(), userdata(e->qos).c_str());
  dds_free(reps);
}

bool seen(dds_entity_t rd, const char* topic) {
  void* s[MAXS] = {nullptr};
  dds_sample_info_t si[MAXS];
  int n = dds_read(rd, s, si, MAXS, MAXS);
  bool hit = false;
  for (int i = 0; i < n; i++)
    if (si[i].valid_data &&
        std::strcmp(static_cast<dds_builtintopic_endpoint_t*>(s[i])->topic_name, topic) == 0)
      hit = true;
  if (n > 0) dds_return_loan(rd, s, n);
  return hit;
}

void discovery(dds_entity_t info) {
  hfsmc::ros2::wire::Raw raw;
  void* one[1] = {&raw};
  dds_sample_info_t si;
  while (dds_take(info, one, &si, 1, 1) > 0)
    if (si.valid_data)
      std::printf("{\"kind\":\"discovery\",\"cdr\":\"%s\"}\n",
                  hex(raw.bytes.data(), raw.bytes.size()).c_str());
  std::fflush(stdout);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: ddsinspect DOMAIN TIMEOUT_S TOPIC...\n");
    return 2;
  }
  dds_entity_t pp = dds_create_participant(static_cast<dds_domainid_t>(std::atoi(argv[1])),
                                           nullptr, nullptr);
  if (pp < 0) {
    std::fprintf(stderr, "ddsinspect: %s\n", dds_strretcode(pp));
    return 2;
  }
  dds_guid_t self;
  dds_get_guid(pp, &self);
  std::printf("{\"kind\":\"self\",\"key\":\"%s\"}\n", hex(self.v, 16).c_str());
  dds_entity_t rp = dds_create_reader(pp, DDS_BUILTIN_TOPIC_DCPSPARTICIPANT, nullptr, nullptr);
  dds_entity_t rw = dds_create_reader(pp, DDS_BUILTIN_TOPIC_DCPSPUBLICATION, nullptr, nullptr);
  dds_entity_t rr = dds_create_reader(pp, DDS_BUILTIN_TOPIC_DCPSSUBSCRIPTION, nullptr, nullptr);
  ddsi_sertype* st =
      hfsmc::ros2::wire::make_sertype("rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_");
  dds_entity_t topic =
      dds_create_topic_sertype(pp, "ros_discovery_info", &st, nullptr, nullptr, nullptr);
  dds_qos_t* q = dds_create_qos();
  dds_qset_reliability(q, DDS_RELIABILITY_RELIABLE, DDS_MSECS(100));
  dds_qset_durability(q, DDS_DURABILITY_TRANSIENT_LOCAL);
  dds_qset_history(q, DDS_HISTORY_KEEP_LAST, 1);
  dds_entity_t info = dds_create_reader(pp, topic, q, nullptr);
  dds_delete_qos(q);
  const dds_time_t end = dds_time() + static_cast<dds_duration_t>(std::atof(argv[2]) * 1e9);
  bool ok = false;
  while (!ok && dds_time() < end) {
    ok = true;
    for (int i = 3; i < argc; i++)
      if (!seen(rw, argv[i]) && !seen(rr, argv[i])) ok = false;
    discovery(info);
    if (!ok) dds_sleepfor(DDS_MSECS(100));
  }
  for (int k = 0; k < 10; ++k) {  // the rest of what was announced with it
    dds_sleepfor(DDS_MSECS(100));
    discovery(info);
  }
  void* s[MAXS] = {nullptr};
  dds_sample_info_t si[MAXS];
  int n = dds_read(rp, s, si, MAXS, MAXS);
  for (int i = 0; i < n; i++) {
    if (!si[i].valid_data) continue;
    auto* p = static_cast<dds_builtintopic_participant_t*>(s[i]);
    std::printf("{\"kind\":\"participant\",\"key\":\"%s\",\"user_data\":\"%s\"}\n",
                hex(p->key.v, 16).c_str(), userdata(p->qos).c_str());
  }
  if (n > 0) dds_return_loan(rp, s, n);
  const dds_entity_t eps[2] = {rw, rr};
  for (int k = 0; k < 2; k++) {
    n = dds_read(eps[k], s, si, MAXS, MAXS);
    for (int i = 0; i < n; i++)
      if (si[i].valid_data)
        endpoint(k ? "subscription" : "publication",
                 static_cast<dds_builtintopic_endpoint_t*>(s[i]));
    if (n > 0) dds_return_loan(eps[k], s, n);
  }
  std::fflush(stdout);
  dds_delete(pp);
  return ok ? 0 : 1;
}
