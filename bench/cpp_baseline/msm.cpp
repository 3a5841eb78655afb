// Boost.MSM peer of the hand-written baselines for bench/cpp.py: the flat toggle
// (-DNESTED=0) or the three-level machine (-DNESTED=1) of bench/models/, each tick an
// event `Tick` that takes the root's one transition ("true": a row without guard).
// Nested: A and B are sub-machines (A: A1: A1a; B: B2: B2b), so the transition exits
// A1a, A1, A and enters B, B2, B2b. The same work as the switch baselines: virtual time
// as a tick counter, the tick at which each level's state was entered, and with
// -DCOUNTED=1 a counter in every entry and exit. MSM's fastest set-up: no message queue,
// no exception handling, no deferred events.
// Usage: msm_flat|msm_nested[_counted] N -> runs N ticks (N transitions), prints a checksum.
#include <cstdio>
#include <cstdlib>

#include <boost/msm/back/state_machine.hpp>
#include <boost/msm/front/functor_row.hpp>
#include <boost/msm/front/state_machine_def.hpp>

#ifndef COUNTED
#define COUNTED 0
#endif
#ifndef NESTED
#define NESTED 0
#endif

namespace {

namespace msm = boost::msm;
namespace mpl = boost::mpl;
using msm::front::Row;
using msm::front::none;

struct Clock {
    long long t = 0;
    long long entered[3] = {0, 0, 0};
    long long n_entry = 0, n_exit = 0;
};
Clock g;

struct Tick {};

// A state at `Level`: entry notes the tick, entry and exit count.
template <int Level>
struct Leaf : msm::front::state<> {
    template <class E, class F> void on_entry(const E&, F&) {
        g.entered[Level] = g.t;
        if (COUNTED) ++g.n_entry;
    }
    template <class E, class F> void on_exit(const E&, F&) {
        if (COUNTED) ++g.n_exit;
    }
};

// The front end of a composite state at `Level` whose one sub-machine starts in `Init`.
template <int Level, class Init, class Tag>
struct Composite : msm::front::state_machine_def<Composite<Level, Init, Tag>> {
    typedef int no_exception_thrown;
    typedef int no_message_queue;
    using initial_state = Init;
    struct transition_table : mpl::vector<> {};
    template <class E, class F> void on_entry(const E&, F&) {
        g.entered[Level] = g.t;
        if (COUNTED) ++g.n_entry;
    }
    template <class E, class F> void on_exit(const E&, F&) {
        if (COUNTED) ++g.n_exit;
    }
    template <class F, class E> void no_transition(const E&, F&, int) {}
};

#if NESTED
struct TagA1 {};
struct TagA {};
struct TagB2 {};
struct TagB {};
using A1 = msm::back::state_machine<Composite<1, Leaf<2>, TagA1>>;
using A = msm::back::state_machine<Composite<0, A1, TagA>>;
using B2 = msm::back::state_machine<Composite<1, Leaf<2>, TagB2>>;
using B = msm::back::state_machine<Composite<0, B2, TagB>>;
#else
struct A : Leaf<0> {};
struct B : Leaf<0> {};
#endif

struct Root_ : msm::front::state_machine_def<Root_> {
    typedef int no_exception_thrown;
    typedef int no_message_queue;
    using initial_state = A;
    struct transition_table : mpl::vector<
        Row<A, Tick, B, none, none>,
        Row<B, Tick, A, none, none>> {};
    template <class F, class E> void no_transition(const E&, F&, int) {}
};
using Root = msm::back::state_machine<Root_>;

}  // namespace

int main(int argc, char** argv) {
    if (argc != 2) {
        std::fprintf(stderr, "usage: %s TICKS\n", argv[0]);
        return 2;
    }
    const long long n = std::atoll(argv[1]);
    Root m;
    m.start();
    for (long long i = 0; i < n; ++i) {
        m.process_event(Tick{});
        ++g.t;
        asm volatile("" : : "r"(&m), "r"(&g) : "memory");  // the wait for the clock (flat.cpp)
    }
    const bool in_a = m.current_state()[0] == 0;
    m.stop();  // exits the active states, innermost first
    std::printf("t=%lld root=%c entered=%lld,%lld,%lld n_entry=%lld n_exit=%lld\n", g.t,
                in_a ? 'A' : 'B', g.entered[0], g.entered[1], g.entered[2], g.n_entry, g.n_exit);
    return 0;
}
