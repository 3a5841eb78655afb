// Boost.Statechart peer of the hand-written baselines for bench/cpp.py: the flat toggle
// (-DNESTED=0) or the three-level machine (-DNESTED=1) of bench/models/, each tick an
// event `Tick` that takes the root's one transition (a `transition` reaction, no guard).
// Nested: A holds A1 holding A1a, B holds B2 holding B2b; the event goes to the innermost
// state first and reaches A's reaction, which exits A1a, A1, A and enters B, B2, B2b.
// The same work as the switch baselines: virtual time as a tick counter, the tick at
// which each level's state was entered (its constructor), and with -DCOUNTED=1 a
// counter in every entry (constructor) and exit (destructor).
// Usage: statechart_flat|statechart_nested[_counted] N -> runs N ticks, prints a checksum.
#include <cstdio>
#include <cstdlib>

#include <boost/statechart/event.hpp>
#include <boost/statechart/simple_state.hpp>
#include <boost/statechart/state_machine.hpp>
#include <boost/statechart/transition.hpp>

#ifndef COUNTED
#define COUNTED 0
#endif
#ifndef NESTED
#define NESTED 0
#endif

namespace {

namespace sc = boost::statechart;

struct Clock {
    long long t = 0;
    long long entered[3] = {0, 0, 0};
    long long n_entry = 0, n_exit = 0;
};
Clock g;

struct Tick : sc::event<Tick> {};

template <int Level>
struct Counted {
    Counted() {
        g.entered[Level] = g.t;
        if (COUNTED) ++g.n_entry;
    }
    ~Counted() {
        if (COUNTED) ++g.n_exit;
    }
};

struct A;
struct B;
struct Machine : sc::state_machine<Machine, A> {};

#if NESTED
struct A1;
struct A1a;
struct B2;
struct B2b;
struct A : sc::simple_state<A, Machine, A1>, Counted<0> {
    using reactions = sc::transition<Tick, B>;
};
struct A1 : sc::simple_state<A1, A, A1a>, Counted<1> {};
struct A1a : sc::simple_state<A1a, A1>, Counted<2> {};
struct B : sc::simple_state<B, Machine, B2>, Counted<0> {
    using reactions = sc::transition<Tick, A>;
};
struct B2 : sc::simple_state<B2, B, B2b>, Counted<1> {};
struct B2b : sc::simple_state<B2b, B2>, Counted<2> {};
#else
struct A : sc::simple_state<A, Machine>, Counted<0> {
    using reactions = sc::transition<Tick, B>;
};
struct B : sc::simple_state<B, Machine>, Counted<0> {
    using reactions = sc::transition<Tick, A>;
};
#endif

}  // namespace

int main(int argc, char** argv) {
    if (argc != 2) {
        std::fprintf(stderr, "usage: %s TICKS\n", argv[0]);
        return 2;
    }
    const long long n = std::atoll(argv[1]);
    Machine m;
    m.initiate();
    const Tick tick;
    for (long long i = 0; i < n; ++i) {
        m.process_event(tick);
        ++g.t;
        asm volatile("" : : "r"(&m), "r"(&g) : "memory");  // the wait for the clock (flat.cpp)
    }
    const bool in_a = m.state_cast<const A*>() != nullptr;
    m.terminate();  // exits the active states, innermost first
    std::printf("t=%lld root=%c entered=%lld,%lld,%lld n_entry=%lld n_exit=%lld\n", g.t,
                in_a ? 'A' : 'B', g.entered[0], g.entered[1], g.entered[2], g.n_entry, g.n_exit);
    return 0;
}
