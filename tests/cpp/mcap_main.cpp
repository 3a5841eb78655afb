// The MCAP writer of the C++ component (templates/cpp/hfsmc/mcap.hpp) driven by
// tests/test_cpp_mcap.py, which reads every file back with the Python `mcap` reader,
// and by bench/mcap.py.
//
//   mcap_main all FILE              every record type, many channels, odd payloads; closed
//   mcap_main ticks FILE N [open]   N ticks of messages, flush_tick() after each, "tick K" on
//                                   stdout after each flush; `open`: then wait to be killed
//   mcap_main bench FILE MB         1 kB messages: MB/s, and the cost of one flush (JSON)
#include <hfsmc/mcap.hpp>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <string>
#include <thread>

namespace {

using hfsmc::mcap::Writer;

// The payload of tick t on channel c; tests/test_cpp_mcap.py computes the same bytes.
std::string payload(unsigned t, unsigned c) {
    std::string s = "t=" + std::to_string(t) + " c=" + std::to_string(c);
    s.push_back('\0');
    s.append((t + c) % 50, static_cast<char>((t * 7 + c) % 256));
    return s;
}

int all(const std::string& path) {
    Writer w(path, "hfsmc-test", "hfsmc mcap.hpp test");
    std::uint16_t json = w.add_schema("hfsmc.Tick", "jsonschema", R"({"type":"object"})");
    std::uint16_t empty = w.add_schema("", "", "");
    std::string binary("\0\x01\xff\0", 4);
    std::uint16_t raw = w.add_schema("bin", "x-bytes", binary);
    (void)raw;
    std::uint16_t first = w.add_channel("/tick", "json", json,
                                        {{"model", "follow_colors.yaml"}, {"note", "vol \xc3\xa0 \xe6\x97\xa5"}});
    std::uint16_t blank = w.add_channel("", "", empty);
    std::uint16_t none = w.add_channel("/no_schema", "x-bytes", 0);
    for (unsigned c = 0; c < 300; ++c) w.add_channel("/many/" + std::to_string(c), "x-bytes");
    w.add_metadata("hfsmc", {{"version", "0.1"}, {"\xc3\xa9t\xc3\xa9", "\xe2\x9c\x93"}, {"", ""}});
    w.add_metadata("", {});
    w.write(first, 1000, R"({"tick":1})");
    w.write(blank, 1000, "");
    w.write(none, 2000, 1500, binary.data(), binary.size());
    std::string large(5U << 20, '\0');
    for (std::size_t i = 0; i < large.size(); ++i) large[i] = static_cast<char>((i * 131) % 251);
    w.write(none, 3000, large);
    w.flush_tick();
    for (unsigned t = 0; t < 3; ++t) {
        for (unsigned c = 0; c < 300; ++c)
            w.write(static_cast<std::uint16_t>(none + 1 + c), 10000 + t, payload(t, c));
        w.flush_tick();
    }
    w.write(first, 500, R"({"tick":0})");  // out of order: statistics keep the least and greatest
    w.close();
    w.close();  // a second close does nothing
    return 0;
}

int ticks(const std::string& path, unsigned n, bool stay_open) {
    Writer w(path);
    std::uint16_t ch[3] = {w.add_channel("/a", "x-bytes", 0, {{"unit", "\xc2\xb5s \xe6\x97\xa5"}}),
                           w.add_channel("/b", "x-bytes"),
                           w.add_channel("/c", "x-bytes")};
    for (unsigned t = 0; t < n; ++t) {
        for (unsigned c = 0; c < 3; ++c) w.write(ch[c], 1000000ULL * t, payload(t, c));
        w.flush_tick();
        std::printf("tick %u\n", t);
        std::fflush(stdout);
    }
    if (stay_open) {
        std::printf("waiting\n");
        std::fflush(stdout);
        for (;;) std::this_thread::sleep_for(std::chrono::seconds(1));
    }
    return 0;
}

int bench(const std::string& path, unsigned mb) {
    using clock = std::chrono::steady_clock;
    std::string msg(1024, 'x');
    Writer w(path);
    std::uint16_t ch = w.add_channel("/bench", "x-bytes");
    unsigned count = mb * 1024;
    auto t0 = clock::now();
    for (unsigned i = 0; i < count; ++i) {
        w.write(ch, i, msg);
        if (i % 1024 == 1023) w.flush_tick();
    }
    w.flush_tick();
    double write_s = std::chrono::duration<double>(clock::now() - t0).count();
    unsigned flushes = 2000;
    auto t1 = clock::now();
    for (unsigned i = 0; i < flushes; ++i) {
        w.write(ch, count + i, std::string_view(msg).substr(0, 64));
        w.flush_tick();
    }
    double flush_s = std::chrono::duration<double>(clock::now() - t1).count();
    w.close();
    std::printf("{\"messages\": %u, \"mb_per_s\": %.1f, \"flush_us\": %.2f}\n", count,
                count * 1024.0 / (1024.0 * 1024.0) / write_s, flush_s / flushes * 1e6);
    return 0;
}

}  // namespace

int main(int argc, char** argv) {
    if (argc < 3) {
        std::cerr << "usage: mcap_main all|ticks|bench FILE [N]\n";
        return 2;
    }
    std::string mode = argv[1];
    try {
        if (mode == "all") return all(argv[2]);
        if (mode == "ticks" && argc >= 4)
            return ticks(argv[2], static_cast<unsigned>(std::atoi(argv[3])),
                         argc >= 5 && std::string(argv[4]) == "open");
        if (mode == "bench" && argc >= 4) return bench(argv[2], static_cast<unsigned>(std::atoi(argv[3])));
    } catch (const std::exception& e) {
        std::cerr << "mcap_main: " << e.what() << "\n";
        return 1;
    }
    std::cerr << "mcap_main: bad arguments\n";
    return 2;
}
