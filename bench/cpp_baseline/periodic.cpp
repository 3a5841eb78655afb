// Control for the real-clock part of bench/cpp.py: a bare C++ loop that wakes at
// absolute deadlines every PERIOD_MS (clock_nanosleep on CLOCK_MONOTONIC with
// TIMER_ABSTIME, missed deadlines skipped) and does nothing else. What this
// machine gives any C++ process that sleeps until a deadline.
// Usage: periodic PERIOD_MS SECONDS -> one line per tick on stdout:
// "DEADLINE_US LATENESS_NS", lateness against the start (the first tick, at t = 0,
// runs at once), as the component measures it from its first tick.
#include <time.h>

#include <cstdio>
#include <cstdlib>
#include <vector>

namespace {

long long now_ns() {
    timespec ts{};
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec * 1000000000LL + ts.tv_nsec;
}

}  // namespace

int main(int argc, char** argv) {
    if (argc != 3) {
        std::fprintf(stderr, "usage: %s PERIOD_MS SECONDS\n", argv[0]);
        return 2;
    }
    const long long period = std::atoll(argv[1]) * 1000000LL;
    const long long until = static_cast<long long>(std::atof(argv[2]) * 1e9);
    std::vector<long long> deadline, late;
    deadline.reserve(static_cast<size_t>(until / period + 2));
    late.reserve(deadline.capacity());
    const long long start = now_ns();
    for (long long t = 0; t <= until;) {
        const long long at = start + t;
        timespec ts{static_cast<time_t>(at / 1000000000LL), static_cast<long>(at % 1000000000LL)};
        while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) != 0) {
        }
        deadline.push_back(t / 1000);
        late.push_back(now_ns() - start - t);
        t += period;
        const long long now = now_ns() - start;
        if (t < now) t += (now - t + period - 1) / period * period;
    }
    for (size_t i = 0; i < late.size(); ++i) std::printf("%lld %lld\n", deadline[i], late[i]);
    return 0;
}
