// Hand-written baseline for bench/cpp.py: the flat toggle of bench/models/flat.yaml
// (and flat_counted.yaml with -DCOUNTED=1) as a plain switch-based periodic FSM,
// with the work a fair hand-written one does and no more:
//   - an enum and a switch per tick;
//   - the condition of the current state's one transition ("true");
//   - exit, then entry (with COUNTED: each increments a counter);
//   - virtual time: a tick counter as the clock (one tick = 1 ms) and the tick
//     at which the current state was entered (what `after` and `elapsed()`
//     need; any periodic FSM with timeouts keeps it).
// Usage: baseline_flat[_counted] N -> runs N ticks (N transitions), prints a checksum.
#include <cstdio>
#include <cstdlib>

#ifndef COUNTED
#define COUNTED 0
#endif

namespace {

enum class State : unsigned char { A, B };

struct Machine {
    long long t = 0;  // ticks since start = ms of virtual time
    State state = State::A;
    long long entered = 0;  // tick at which `state` was entered
    long long n_entry = 0;
    long long n_exit = 0;

    void enter(State s) {
        state = s;
        entered = t;
        if (COUNTED) ++n_entry;
    }
    void leave() {
        if (COUNTED) ++n_exit;
    }

    void tick() {
        switch (state) {
        case State::A:
            if (true) {  // when: true
                leave();
                enter(State::B);
            }
            break;
        case State::B:
            if (true) {
                leave();
                enter(State::A);
            }
            break;
        }
        ++t;
    }
};

}  // namespace

int main(int argc, char** argv) {
    if (argc != 2) {
        std::fprintf(stderr, "usage: %s TICKS\n", argv[0]);
        return 2;
    }
    const long long n = std::atoll(argv[1]);
    Machine m;
    m.enter(State::A);
    for (long long i = 0; i < n; ++i) {
        m.tick();
        // Between two ticks a real periodic FSM waits for its clock, an opaque
        // call: the machine lives in memory and the compiler cannot fuse ticks
        // or fold the loop into a formula. This empty asm says just that and
        // costs no instruction.
        asm volatile("" : : "r"(&m) : "memory");
    }
    m.leave();  // stop: exit the active state
    std::printf("t=%lld state=%c entered=%lld n_entry=%lld n_exit=%lld\n", m.t,
                m.state == State::A ? 'A' : 'B', m.entered, m.n_entry, m.n_exit);
    return 0;
}
