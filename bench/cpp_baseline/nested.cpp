// Hand-written baseline for bench/cpp.py: the three-level machine of
// bench/models/nested.yaml (and nested_counted.yaml with -DCOUNTED=1) as a plain
// switch-based hierarchical periodic FSM, with the work a fair hand-written one
// does and no more:
//   - one enum and one switch per sub-automaton (the root's: A, B; A's: A1;
//     A1's: A1a; B's: B2; B2's: B2b), each child ticked by its parent's tick,
//     parents first, as in any hierarchical FSM;
//   - the condition of the root state's one transition ("true");
//   - a cross-branch transition A -> B: exits innermost first (A1a, A1, A),
//     entries outermost first (B, B2, B2b), each entry starting its
//     sub-automaton in its initial state (with COUNTED: every entry and exit
//     increments a counter, 6 actions per transition);
//   - virtual time: a tick counter as the clock (one tick = 1 ms) and, for every
//     level, the tick at which its current state was entered (what `after` and
//     `elapsed()` need).
// Usage: baseline_nested[_counted] N -> runs N ticks (N transitions), prints a checksum.
#include <cstdio>
#include <cstdlib>

#ifndef COUNTED
#define COUNTED 0
#endif

namespace {

enum class Root : unsigned char { A, B };
enum class InA : unsigned char { A1 };
enum class InA1 : unsigned char { A1a };
enum class InB : unsigned char { B2 };
enum class InB2 : unsigned char { B2b };

struct Machine {
    long long t = 0;  // ticks since start = ms of virtual time
    Root root = Root::A;
    InA in_a = InA::A1;
    InA1 in_a1 = InA1::A1a;
    InB in_b = InB::B2;
    InB2 in_b2 = InB2::B2b;
    long long entered[3] = {0, 0, 0};  // per level: tick at which its state was entered
    long long n_entry = 0;
    long long n_exit = 0;

    void count_entry() {
        if (COUNTED) ++n_entry;
    }
    void count_exit() {
        if (COUNTED) ++n_exit;
    }

    // Entries: own code, then the sub-automaton's initial state.
    void enter_A1a() { in_a1 = InA1::A1a; entered[2] = t; count_entry(); }
    void enter_A1() { in_a = InA::A1; entered[1] = t; count_entry(); enter_A1a(); }
    void enter_A() { root = Root::A; entered[0] = t; count_entry(); enter_A1(); }
    void enter_B2b() { in_b2 = InB2::B2b; entered[2] = t; count_entry(); }
    void enter_B2() { in_b = InB::B2; entered[1] = t; count_entry(); enter_B2b(); }
    void enter_B() { root = Root::B; entered[0] = t; count_entry(); enter_B2(); }

    // Exits: the active child first, then own code.
    void exit_A1() {
        switch (in_a1) {
        case InA1::A1a: count_exit(); break;
        }
        count_exit();
    }
    void exit_A() {
        switch (in_a) {
        case InA::A1: exit_A1(); break;
        }
        count_exit();
    }
    void exit_B2() {
        switch (in_b2) {
        case InB2::B2b: count_exit(); break;
        }
        count_exit();
    }
    void exit_B() {
        switch (in_b) {
        case InB::B2: exit_B2(); break;
        }
        count_exit();
    }
    void exit_root() {
        switch (root) {
        case Root::A: exit_A(); break;
        case Root::B: exit_B(); break;
        }
    }

    // Ticks of the inner sub-automata: their states have no transition and no
    // `during`, so each is a switch with nothing to do, as written by hand.
    void tick_A1() {
        switch (in_a1) {
        case InA1::A1a: break;
        }
    }
    void tick_A() {
        switch (in_a) {
        case InA::A1: tick_A1(); break;
        }
    }
    void tick_B2() {
        switch (in_b2) {
        case InB2::B2b: break;
        }
    }
    void tick_B() {
        switch (in_b) {
        case InB::B2: tick_B2(); break;
        }
    }

    void tick() {
        switch (root) {  // the root's tick: its transition, then the active child's tick
        case Root::A:
            if (true) {  // when: true
                exit_A();
                enter_B();
            }
            break;
        case Root::B:
            if (true) {
                exit_B();
                enter_A();
            }
            break;
        }
        switch (root) {
        case Root::A: tick_A(); break;
        case Root::B: tick_B(); break;
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
    m.enter_A();
    for (long long i = 0; i < n; ++i) {
        m.tick();
        // Between two ticks a real periodic FSM waits for its clock, an opaque
        // call: the machine lives in memory and the compiler cannot fuse ticks
        // or fold the loop into a formula. This empty asm says just that and
        // costs no instruction.
        asm volatile("" : : "r"(&m) : "memory");
    }
    m.exit_root();  // stop: exit the active states, innermost first
    std::printf("t=%lld root=%c entered=%lld,%lld,%lld n_entry=%lld n_exit=%lld\n", m.t,
                m.root == Root::A ? 'A' : 'B', m.entered[0], m.entered[1], m.entered[2],
                m.n_entry, m.n_exit);
    return 0;
}
