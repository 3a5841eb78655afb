/* hfsmc driver
kind: gadget
class: Gadget
doc: A UDP distance sensor with a LED and a buzzer.
snapshot: {distance: .inf, age: .inf, count: 0, led: false}
options: {stale: 1.0}
queries:
  - "distance(): Metres to the obstacle in front; inf before the first reading."
  - "age(): Seconds since the latest reading; inf before the first."
  - "ok(): Readings are coming: the latest is younger than the `stale` option."
  - "count(): Readings received so far."
  - "led_on(): The LED is on, as the device last said."
commands:
  - "led(on): Switch the LED on or off."
  - "beep(ms): Sound the buzzer for `ms` milliseconds."
*/
// The C++ driver of examples/udp_gadget (its Python twin: gadget.py, the same
// behaviour and the same lines on stderr). The device answers whoever said `HELLO`
// last with `D <metres> <led 0|1>` 20 times a second and obeys `LED <0|1>` and
// `BEEP <ms>`; a thread listens, says HELLO every half second until readings come,
// and keeps the latest under a mutex.
#pragma once

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <mutex>
#include <string>

#include "hfsmc/driver.hpp"

struct GadgetSnap {
    double distance = std::numeric_limits<double>::infinity();
    double age = std::numeric_limits<double>::infinity();
    long long count = 0;
    bool led = false;
    static std::vector<hfsmc::Field> fields(GadgetSnap& s) {
        return {{"distance", &s.distance}, {"age", &s.age}, {"count", &s.count}, {"led", &s.led}};
    }
};

class Gadget : public hfsmc::Driver<GadgetSnap> {
public:
    Gadget(const std::string& name, const std::string& url, const Options& options)
        : Driver("gadget", name, url.empty() ? "udp:127.0.0.1:9870" : url, options, {{"stale", "1.0"}}) {
        stale_ = option_number("stale");
        if (!live()) return;
        const std::string u = this->url();
        const auto colon = u.rfind(':');
        const std::string host = u.rfind("udp:", 0) == 0 && colon > 4 ? u.substr(4, colon - 4) : "";
        const int port = colon == std::string::npos ? 0 : std::atoi(u.c_str() + colon + 1);
        device_.sin_family = AF_INET;
        device_.sin_port = htons(static_cast<uint16_t>(port));
        if (host.empty() || port <= 0 || port > 65535 || inet_pton(AF_INET, host.c_str(), &device_.sin_addr) != 1) {
            say("cannot start: write udp:HOST:PORT (an IPv4 address), not `" + u + "`");
            std::exit(1);
        }
        fd_ = ::socket(AF_INET, SOCK_DGRAM, 0);
        sockaddr_in local{};
        local.sin_family = AF_INET;
        local.sin_addr.s_addr = htonl(host.rfind("127.", 0) == 0 ? INADDR_LOOPBACK : INADDR_ANY);
        if (fd_ < 0 || ::bind(fd_, reinterpret_cast<sockaddr*>(&local), sizeof local) != 0) {
            say("cannot start: no UDP socket");
            std::exit(1);
        }
        start_thread([this] { listen(); });
    }
    ~Gadget() override {
        stop();
        if (fd_ >= 0) ::close(fd_);
    }

    /// Metres to the obstacle in front; inf before the first reading.
    double distance() const { return snap("distance").distance; }
    /// Seconds since the latest reading; inf before the first.
    double age() const { return snap("age").age; }
    /// Readings are coming: the latest is younger than the `stale` option.
    bool ok() const { return snap("ok").age < stale_; }
    /// Readings received so far.
    long long count() const { return snap("count").count; }
    /// The LED is on, as the device last said.
    bool led_on() const { return snap("led_on").led; }

    /// Switch the LED on or off.
    void led(bool on) {
        if (command("led", on ? "[true]" : "[false]")) send(on ? "LED 1" : "LED 0");
    }
    /// Sound the buzzer for `ms` milliseconds.
    void beep(long long ms) {
        if (command("beep", "[" + std::to_string(ms) + "]")) send("BEEP " + std::to_string(ms));
    }

protected:
    void read(GadgetSnap& latest) override {
        std::lock_guard<std::mutex> lock(mutex_);
        if (count_ == 0) return;
        latest.distance = distance_;
        latest.led = led_;
        latest.count = count_;
        latest.age = std::chrono::duration<double>(Clock::now() - at_).count();
    }

private:
    using Clock = std::chrono::steady_clock;

    void send(const std::string& text) {
        ::sendto(fd_, text.data(), text.size(), 0, reinterpret_cast<const sockaddr*>(&device_), sizeof device_);
    }

    void listen() {
        Clock::time_point hello{};
        std::string said;
        long bad = 0;
        while (!stopping()) {
            const Clock::time_point now = Clock::now();
            bool stale;
            {
                std::lock_guard<std::mutex> lock(mutex_);
                stale = count_ == 0 || std::chrono::duration<double>(now - at_).count() > stale_;
            }
            if (stale && now - hello > std::chrono::milliseconds(500)) {
                hello = now;
                send("HELLO");
            }
            if (stale && said == "readings") {
                said = "stale";
                say("no reading for " + hfsmc::float_repr(stale_) + " s");
            }
            pollfd pfd{fd_, POLLIN, 0};
            if (::poll(&pfd, 1, 100) <= 0) continue;
            char buf[512];
            const ssize_t n = ::recv(fd_, buf, sizeof buf - 1, 0);
            if (n <= 0) continue;
            buf[n] = '\0';
            double metres = 0;
            int led = 0, used = 0;
            if (std::sscanf(buf, "D %lf %d%n", &metres, &led, &used) != 2 || used != n || (led != 0 && led != 1)) {
                if (++bad == 1) say("a datagram that is no reading (dropped): " + std::string(buf, std::min<ssize_t>(n, 40)));
                continue;
            }
            {
                std::lock_guard<std::mutex> lock(mutex_);
                distance_ = metres;
                led_ = led == 1;
                at_ = Clock::now();
                ++count_;
            }
            if (said != "readings") {
                say("readings from " + url() + (said.empty() ? "" : " again"));
                said = "readings";
            }
        }
    }

    double stale_ = 1.0;
    int fd_ = -1;
    sockaddr_in device_{};
    std::mutex mutex_;
    double distance_ = 0;
    bool led_ = false;
    long long count_ = 0;
    Clock::time_point at_{};
};
