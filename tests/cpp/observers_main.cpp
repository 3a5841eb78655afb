// Plays a fixed run of a small two-level automaton (the blinker of tests/support.py)
// through the C++ observers, as the runtime would call them, for tests/test_cpp_observers.py.
//
//   observers_main [--monitor ADDR] [--display] [--focus PATH] [--no-autofocus]
//                  [--calls FILE] [--gate FILE] [--gate-at N] [--burst N] [--pause-ms N] [--masks]
//                  [--feeds] [--regions] [--use]
//   observers_main --parse ADDR      prints HOST PORT, or the error and exits 2
//   observers_main --readable        prints hfsmc::readable of each line of stdin
//   observers_main --fit             prints view_detail::fit's T L V for each FREE T L V of stdin
//
// --calls writes every observer call as a JSON line ({"record": ...} / {"sample": ...});
// --gate waits (up to 20 s) for FILE to exist after the first N calls (--gate-at, 9 by
// default: the run is then in Blinking/Dark), saying so on stderr; a second --gate-at
// waits for FILE.1, and so on. --burst adds N log records after the 9th call; --masks
// prints each thread's blocked signals there. --feeds registers a stand-in vehicle and
// camera (hfsmc::Feed, as mavlink.hpp and camera.hpp do): the camera has a new frame at
// every call. --regions plays the run of a state with two regions instead
// (PARALLEL_STRUCTURE and PARALLEL_TRACE of tests/support.py). --use says that Blinking's
// sub-automaton is used from lib/blink.yaml (the structure's "use"), the run unchanged.
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <dirent.h>
#include <unistd.h>

#include "hfsmc/monitor.hpp"
#include "hfsmc/view.hpp"

namespace {

std::vector<std::unique_ptr<hfsmc::Observer>> observers;

class FakeVehicle : public hfsmc::Feed {
public:
    const char* feed_kind() const override { return "vehicle"; }
    std::string feed_name() const override { return "drone"; }
    std::string feed_message(long long t_ms) override {
        return "{\"type\":\"vehicle\",\"t\":" + std::to_string(t_ms) +
               ",\"name\":\"drone\",\"connected\":true,\"mode\":\"GUIDED\",\"armed\":true,"
               "\"altitude\":2.346,\"position\":[1.000,-2.500,-2.346],\"velocity\":null,"
               "\"battery\":87,\"link_age\":0.25}";
    }
};

class FakeCamera : public hfsmc::Feed {
public:
    const char* feed_kind() const override { return "camera"; }
    std::string feed_name() const override { return "camera"; }
    std::string feed_message(long long t_ms) override {
        ++frames;
        return "{\"type\":\"frame\",\"t\":" + std::to_string(t_ms) +
               ",\"name\":\"camera\",\"width\":1,\"height\":1,\"jpeg\":\"" + std::to_string(frames) + "\"}";
    }
    void feed_reset() override { ++resets; }
    long frames = 0, resets = 0;
};
std::ofstream calls;
int pause_ms = 0;
std::string gate;
std::vector<int> gates;  // call counts where the run waits
int made = 0;
bool regions = false;
bool use = false;
std::vector<std::string> variable_names = {"led", "count", "pauses"};

void step() {  // after each observer call
    ++made;
    std::size_t i = 0;
    while (i < gates.size() && gates[i] != made) ++i;
    if (i == gates.size() || gate.empty()) return;
    std::string file = i ? gate + "." + std::to_string(i) : gate;
    std::fprintf(stderr, "component: at the gate\n");
    std::fflush(stderr);
    for (int k = 0; k < 2000 && access(file.c_str(), F_OK) != 0; ++k) {
        std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    std::fprintf(stderr, "component: past the gate\n");
    std::fflush(stderr);
}

hfsmc::Structure parallel_structure() {
    hfsmc::Structure s;
    s.name = "par";
    s.automata = {{"", "", "", 100, "Mission", false}, {"Mission", "Nav", "", 100, "A", false},
                  {"Mission", "Watch", "", 300, "Ok", true}};
    s.states = {{"Mission", false, true}, {"Mission/Nav/A", false, false}, {"Mission/Nav/B", true, false},
                {"Mission/Watch/Ok", false, false}, {"Mission/Watch/Seen", true, false}, {"Done", true, false}};
    s.transitions = {{"Mission", "Done", 0, "all done"}, {"Mission/Nav/A", "Mission/Nav/B", 0, ""},
                     {"Mission/Watch/Ok", "Mission/Watch/Seen", 0, "seen"}};
    s.variables = {"n"};
    return s;
}

hfsmc::Structure structure() {
    if (regions) return parallel_structure();
    hfsmc::Structure s;
    s.name = "blinker";
    s.automata = {{"", "", "", 100, "Blinking", false},
                  {"Blinking", "", use ? "lib/blink.yaml" : "", 50, "Lit", true}};
    s.states = {{"Blinking", false, true}, {"Blinking/Lit", false, false}, {"Blinking/Dark", false, false},
                {"Paused", false, false}, {"Done", true, false}};
    s.transitions = {{"Blinking", "Done", 0, "enough"}, {"Blinking", "Paused", 1, "pause"},
                     {"Blinking/Lit", "Blinking/Dark", 0, ""}, {"Blinking/Dark", "Blinking/Lit", 0, ""},
                     {"Paused", "Blinking", 0, "resume"}};
    s.variables = {"led", "count", "pauses"};
    s.parameters = {{"blinks", "10"}};
    return s;
}

void emit(hfsmc::Record r) {
    using hfsmc::json_string;
    std::string j = "{\"t\":" + std::to_string(r.t) + ",\"ev\":" + json_string(r.ev);
    if (r.ev == "start") j += ",\"name\":" + json_string(r.name);
    if (r.ev == "enter" || r.ev == "exit" || r.ev == "log" || r.ev == "error") j += ",\"state\":" + json_string(r.state);
    if (r.ev == "fire") {
        j += ",\"from\":" + json_string(r.from) + ",\"to\":" + json_string(r.to) + ",\"index\":" + std::to_string(r.index);
    }
    if (r.ev == "log") j += ",\"msg\":" + json_string(r.msg);
    if (r.ev == "error") j += ",\"snippet\":" + json_string(r.snippet);
    if (r.ev == "interrupt" || r.ev == "stop") j += ",\"reason\":" + json_string(r.reason);
    if (r.ev == "interrupt") j += ",\"to\":" + json_string(r.to);
    r.json = j + "}";
    if (calls.is_open()) calls << "{\"record\":" << r.json << "}\n";
    for (auto& o : observers) o->record(r);
    step();
}

hfsmc::Record rec(long long t, const char* ev) {
    hfsmc::Record r;
    r.t = t;
    r.ev = ev;
    return r;
}
hfsmc::Record at(long long t, const char* ev, const std::string& state) {
    hfsmc::Record r = rec(t, ev);
    r.state = state;
    return r;
}
hfsmc::Record fire(long long t, const std::string& from, const std::string& to, int index) {
    hfsmc::Record r = rec(t, "fire");
    r.from = from, r.to = to, r.index = index;
    return r;
}
hfsmc::Record log(long long t, const std::string& state, const std::string& msg) {
    hfsmc::Record r = at(t, "log", state);
    r.msg = msg;
    return r;
}

// The blinker's leaf transition at t: fired, the leaf left, the other entered.
void blink(long long t, const std::string& from, const std::string& to) {
    emit(fire(t, from, to, 0));
    emit(at(t, "exit", from));
    emit(at(t, "enter", to));
}

void sample(long long t, const std::vector<std::string>& values, long long overruns) {
    if (calls.is_open()) {
        calls << "{\"sample\":{\"t\":" << t << ",\"variables\":{";
        for (std::size_t i = 0; i < values.size(); ++i) {
            calls << (i ? "," : "") << hfsmc::json_string(variable_names[i]) << ":" << hfsmc::json_string(values[i]);
        }
        calls << "},\"overruns\":" << overruns << "}}\n";
    }
    for (auto& o : observers) o->sample(t, values, overruns, -1);
    std::this_thread::sleep_for(std::chrono::milliseconds(pause_ms));
    step();
}

// The run of PARALLEL_TRACE (tests/support.py): both regions active, each takes a
// transition, the state is left (regions exited in reverse order), the run stops.
// The 9th call is the sample at 600 ms, both regions half way.
void play_regions() {
    hfsmc::Record start = rec(0, "start");
    start.name = "par";
    emit(start);
    emit(at(0, "enter", "Mission"));
    emit(at(0, "enter", "Mission/Nav/A"));
    emit(at(0, "enter", "Mission/Watch/Ok"));
    sample(0, {"0"}, 0);
    emit(fire(200, "Mission/Nav/A", "Mission/Nav/B", 0));
    emit(at(200, "exit", "Mission/Nav/A"));
    emit(at(200, "enter", "Mission/Nav/B"));
    sample(600, {"2"}, 0);
    emit(fire(900, "Mission/Watch/Ok", "Mission/Watch/Seen", 0));
    emit(at(900, "exit", "Mission/Watch/Ok"));
    emit(at(900, "enter", "Mission/Watch/Seen"));
    emit(log(900, "Mission/Watch/Seen", "seen"));
    sample(950, {"3"}, 1);
    emit(fire(1000, "Mission", "Done", 0));
    emit(at(1000, "exit", "Mission/Watch/Seen"));
    emit(at(1000, "exit", "Mission/Nav/B"));
    emit(at(1000, "exit", "Mission"));
    emit(at(1000, "enter", "Done"));
    emit(at(1000, "exit", "Done"));
    hfsmc::Record stop = rec(1000, "stop");
    stop.reason = "final";
    emit(stop);
}

void print_masks() {
    DIR* d = opendir("/proc/self/task");
    while (dirent* e = d ? readdir(d) : nullptr) {
        if (e->d_name[0] == '.') continue;
        std::ifstream status(std::string("/proc/self/task/") + e->d_name + "/status");
        std::string line;
        while (std::getline(status, line)) {
            if (line.rfind("SigBlk:", 0) == 0) std::printf("task %s %s\n", e->d_name, line.c_str());
        }
    }
    if (d) closedir(d);
    std::printf("main %d\n", static_cast<int>(getpid()));
    std::fflush(stdout);
}

}  // namespace

int main(int argc, char** argv) {
    int burst = 0;
    bool masks = false;
    try {
        for (int i = 1; i < argc; ++i) {
            std::string a = argv[i];
            auto value = [&]() -> std::string {
                if (i + 1 >= argc) throw std::invalid_argument(a + " needs a value");
                return argv[++i];
            };
            if (a == "--readable") {
                std::string line;
                while (std::getline(std::cin, line)) std::printf("%s\n", hfsmc::readable(line).c_str());
                return 0;
            } else if (a == "--fit") {
                long long free;
                std::size_t t, l, v;
                while (std::cin >> free >> t >> l >> v) {
                    const auto k = hfsmc::view_detail::fit(free, {t, l, v});
                    std::printf("%zu %zu %zu\n", k.transitions, k.logs, k.variables);
                }
                return 0;
            } else if (a == "--parse") {
                auto [host, port] = hfsmc::parse_monitor_address(value());
                std::printf("%s %d\n", host.c_str(), port);
                return 0;
            } else if (a == "--monitor") {
                auto [host, port] = hfsmc::parse_monitor_address(value());
                observers.push_back(std::make_unique<hfsmc::MonitorServer>(host, port));
            } else if (a == "--display" || a == "--focus" || a == "--no-autofocus") {
                std::string focus;
                bool autofocus = true;
                for (int k = 1; k < argc; ++k) {
                    if (std::string(argv[k]) == "--focus" && k + 1 < argc) focus = argv[k + 1];
                    if (std::string(argv[k]) == "--no-autofocus") autofocus = false;
                }
                if (a == "--focus") ++i;
                bool have = false;
                for (auto& o : observers) have |= dynamic_cast<hfsmc::Display*>(o.get()) != nullptr;
                if (!have) observers.push_back(std::make_unique<hfsmc::Display>(stdout, focus, autofocus));
            } else if (a == "--calls") {
                calls.open(value());
            } else if (a == "--gate") {
                gate = value();
            } else if (a == "--gate-at") {
                gates.push_back(std::stoi(value()));
            } else if (a == "--burst") {
                burst = std::stoi(value());
            } else if (a == "--pause-ms") {
                pause_ms = std::stoi(value());
            } else if (a == "--regions") {
                regions = true;
                variable_names = {"n"};
            } else if (a == "--use") {
                use = true;
            } else if (a == "--masks") {
                masks = true;
            } else if (a == "--feeds") {
                static FakeVehicle vehicle;
                static FakeCamera camera;
                hfsmc::register_feed(&vehicle);
                hfsmc::register_feed(&camera);
            } else {
                throw std::invalid_argument("unknown argument " + a);
            }
        }
    } catch (const std::exception& e) {
        std::fprintf(stderr, "error: %s\n", e.what());
        return 2;
    }
    if (gates.empty()) gates.push_back(9);

    for (auto& o : observers) o->start(structure());
    if (regions) {
        play_regions();
        for (auto& o : observers) o->close();
        observers.clear();
        std::fprintf(stderr, "closed\n");
        return 0;
    }
    hfsmc::Record start = rec(0, "start");
    start.name = "blinker";
    emit(start);
    emit(at(0, "enter", "Blinking"));
    emit(at(0, "enter", "Blinking/Lit"));
    sample(0, {"True", "0", "0"}, 0);
    blink(500, "Blinking/Lit", "Blinking/Dark");
    emit(log(500, "Blinking/Dark", "dark \"now\" \\ caf\xc3\xa9 \xe2\x9c\x93 \xf0\x9f\x9a\x81 \x1b[2J\ttab"));
    sample(600, {"False", "1", "0"}, 2);
    if (masks) print_masks();
    std::string filler(80, 'x');
    for (int k = 0; k < burst; ++k) emit(log(700, "Blinking/Dark", "burst " + std::to_string(k) + " " + filler));
    blink(1000, "Blinking/Dark", "Blinking/Lit");
    sample(1100, {"True", "2", "0"}, 2);
    emit(fire(3000, "Blinking", "Paused", 1));
    emit(at(3000, "exit", "Blinking/Lit"));
    emit(at(3000, "exit", "Blinking"));
    emit(at(3000, "enter", "Paused"));
    emit(log(3000, "Paused", "paused with the LED off"));
    sample(3050, {"False", "2", "1"}, 3);
    hfsmc::Record error = at(3100, "error", "Paused");
    error.snippet = "during";
    emit(error);
    hfsmc::Record interrupt = rec(3100, "interrupt");
    interrupt.reason = "error", interrupt.to = "Done";
    emit(interrupt);
    emit(at(3100, "exit", "Paused"));
    emit(at(3100, "enter", "Done"));
    emit(at(3100, "exit", "Done"));
    emit(log(3100, "", "stopped after 2 blinks and 1 pauses"));
    hfsmc::Record stop = rec(3100, "stop");
    stop.reason = "error";
    emit(stop);
    auto t0 = std::chrono::steady_clock::now();
    for (auto& o : observers) o->close();
    observers.clear();
    long long ms = std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::steady_clock::now() - t0).count();
    std::fprintf(stderr, "closed in %lld ms\n", ms);
    return 0;
}
