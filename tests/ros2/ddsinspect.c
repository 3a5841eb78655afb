/* What a ROS 2 tool on Cyclone DDS 0.10 (ROS 2 Humble's and Jazzy's DDS, Debian's
 * cyclonedds-dev) sees of a domain, from DDS's built-in topics: participants, publications
 * and subscriptions with their topic and type names, QoS and USER_DATA, one JSON object a
 * line on stdout (tests/test_ros2_wire.py).
 *
 * usage: ddsinspect DOMAIN TIMEOUT_S TOPIC...
 * Waits until a publication or subscription of each TOPIC is seen (exit 0) or the timeout
 * passes (exit 1), then prints everything seen. */
#include <dds/dds.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define MAXS 256

static void hex(const unsigned char *p, size_t n) {
  for (size_t i = 0; i < n; i++) printf("%02x", p[i]);
}

static void userdata(const dds_qos_t *qos) {
  void *v = NULL;
  size_t sz = 0;
  printf("\"user_data\":\"");
  if (qos && dds_qget_userdata(qos, &v, &sz) && v) hex(v, sz);
  printf("\"");
  dds_free(v);
}

static void endpoint(const char *kind, const dds_builtintopic_endpoint_t *e) {
  dds_reliability_kind_t rel = DDS_RELIABILITY_BEST_EFFORT;
  dds_duration_t blocking = 0;
  dds_durability_kind_t dur = DDS_DURABILITY_VOLATILE;
  dds_history_kind_t hist = DDS_HISTORY_KEEP_LAST;
  int32_t depth = 0;
  uint32_t nrep = 0;
  dds_data_representation_id_t *reps = NULL;
  dds_qget_reliability(e->qos, &rel, &blocking);
  dds_qget_durability(e->qos, &dur);
  dds_qget_history(e->qos, &hist, &depth);
  dds_qget_data_representation(e->qos, &nrep, &reps);
  printf("{\"kind\":\"%s\",\"key\":\"", kind);
  hex(e->key.v, 16);
  printf("\",\"participant\":\"");
  hex(e->participant_key.v, 16);
  printf("\",\"topic\":\"%s\",\"type\":\"%s\",\"reliable\":%s,\"transient_local\":%s,"
         "\"keep_last\":%s,\"depth\":%d,\"representation\":[",
         e->topic_name, e->type_name, rel == DDS_RELIABILITY_RELIABLE ? "true" : "false",
         dur == DDS_DURABILITY_TRANSIENT_LOCAL ? "true" : "false",
         hist == DDS_HISTORY_KEEP_LAST ? "true" : "false", (int)depth);
  for (uint32_t i = 0; i < nrep; i++) printf("%s%d", i ? "," : "", (int)reps[i]);
  printf("],");
  userdata(e->qos);
  printf("}\n");
  dds_free(reps);
}

static int seen(dds_entity_t rd, const char *topic) {
  void *s[MAXS] = {0};
  dds_sample_info_t si[MAXS];
  int n = dds_read(rd, s, si, MAXS, MAXS), hit = 0;
  for (int i = 0; i < n; i++)
    if (si[i].valid_data && strcmp(((dds_builtintopic_endpoint_t *)s[i])->topic_name, topic) == 0)
      hit = 1;
  if (n > 0) dds_return_loan(rd, s, n);
  return hit;
}

int main(int argc, char **argv) {
  if (argc < 3) {
    fprintf(stderr, "usage: ddsinspect DOMAIN TIMEOUT_S TOPIC...\n");
    return 2;
  }
  dds_entity_t pp = dds_create_participant((dds_domainid_t)atoi(argv[1]), NULL, NULL);
  if (pp < 0) {
    fprintf(stderr, "ddsinspect: %s\n", dds_strretcode(pp));
    return 2;
  }
  dds_entity_t rp = dds_create_reader(pp, DDS_BUILTIN_TOPIC_DCPSPARTICIPANT, NULL, NULL);
  dds_entity_t rw = dds_create_reader(pp, DDS_BUILTIN_TOPIC_DCPSPUBLICATION, NULL, NULL);
  dds_entity_t rr = dds_create_reader(pp, DDS_BUILTIN_TOPIC_DCPSSUBSCRIPTION, NULL, NULL);
  dds_time_t end = dds_time() + (dds_duration_t)(atof(argv[2]) * 1e9);
  int ok = 0;
  while (!ok && dds_time() < end) {
    ok = 1;
    for (int i = 3; i < argc; i++)
      if (!seen(rw, argv[i]) && !seen(rr, argv[i])) ok = 0;
    if (!ok) dds_sleepfor(DDS_MSECS(100));
  }
  dds_sleepfor(DDS_MSECS(300)); /* the rest of what was announced with it */
  void *s[MAXS] = {0};
  dds_sample_info_t si[MAXS];
  int n = dds_read(rp, s, si, MAXS, MAXS);
  for (int i = 0; i < n; i++) {
    if (!si[i].valid_data) continue;
    dds_builtintopic_participant_t *p = s[i];
    printf("{\"kind\":\"participant\",\"key\":\"");
    hex(p->key.v, 16);
    printf("\",");
    userdata(p->qos);
    printf("}\n");
  }
  if (n > 0) dds_return_loan(rp, s, n);
  dds_entity_t eps[2] = {rw, rr};
  for (int k = 0; k < 2; k++) {
    n = dds_read(eps[k], s, si, MAXS, MAXS);
    for (int i = 0; i < n; i++)
      if (si[i].valid_data) endpoint(k ? "subscription" : "publication", s[i]);
    if (n > 0) dds_return_loan(eps[k], s, n);
  }
  fflush(stdout);
  dds_delete(pp);
  return ok ? 0 : 1;
}
