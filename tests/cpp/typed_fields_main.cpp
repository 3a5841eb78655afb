// tests/cpp/typed_fields_main.cpp: the driver base's typed fields (hfsmc/driver.hpp:
// Numbers, Wholes, Texts) and its warning at stop, on a driver of its own; run by
// tests/test_cpp_drivers.py, which compares what it prints with the Python driver base.
#include <cstdio>
#include <map>
#include <string>
#include <vector>

#include "hfsmc/driver.hpp"

namespace {

struct ArmSnap {
  double at[3] = {1.5, std::numeric_limits<double>::quiet_NaN(), -2.0};
  long long span[2] = {3, 7};
  std::map<std::string, std::string> acks{{"grip", "accepted"}, {"home", "pending"}};
  bool busy = true;
  static std::vector<hfsmc::Field> fields(ArmSnap& s) {
    return {{"at", hfsmc::Numbers{s.at, 3, "[x, y, z]"}}, {"span", hfsmc::Wholes{s.span, 2}},
            {"acks", &s.acks}, {"busy", &s.busy}};
  }
};

class Arm : public hfsmc::Driver<ArmSnap> {
 public:
  Arm() : Driver("arm", "arm", "udp:127.0.0.1:9", {}, {}) {}
  ~Arm() override { stop(); }

 private:
  void read(ArmSnap&) override {}
  std::string stop_warning() const override { return current().busy ? "still gripping" : ""; }
};

}  // namespace

int main() {
  Arm arm;
  arm.take_snapshot(0);
  std::printf("fields {%s}\n", arm.snapshot_fields().c_str());
  std::printf("schema %s\n", arm.snapshot_schema().c_str());
  std::printf("warning %s\n", hfsmc::warning_at_stop(arm).c_str());
  std::printf("lockstep %lld\n", arm.lockstep_sent());
  return 0;
}
