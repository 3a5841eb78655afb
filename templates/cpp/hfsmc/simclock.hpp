// hfsmc: `--clock sim[:[HOST:]PORT]`: the component takes its instants at the simulated
// time of `hfsmc sim --lockstep PORT` (schemas/lockstep.md, docs/component.md#clocks).
//
// The C++ twin of templates/python/hfsmc_simclock.py, with the same messages. Before each
// instant at t the engine calls advance(t): the component tells the simulator how many
// MAVLink datagrams it has sent in all and that it wants to be woken at t; the simulator
// applies them, steps to t and answers how many datagrams it has sent and which camera
// frame is its latest; each driver (Synced) then waits, bounded, until it holds them.
// Nothing here reads the wall clock except to bound the waits.
#pragma once

#include <arpa/inet.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <string>
#include <map>
#include <thread>
#include <vector>

namespace hfsmc {
namespace simclock {

constexpr const char* kProtocol = "hfsmc-lockstep";
constexpr int kVersion = 1;
constexpr int kDefaultPort = 14560;
constexpr double kConnectWaitS = 30.0;  // the simulator may still be starting
constexpr double kAnswerWaitS = 30.0;   // a simulator silent that long is taken for gone
constexpr long long kMaxStepUs = 100000;  // the drivers' own work runs this often at least

struct Gone : std::runtime_error {  // the simulator has stopped, died or broken the protocol
    using std::runtime_error::runtime_error;
};

struct Step {  // the simulator's answer: at t, `sent` datagrams in all, its latest frame
    long long t = -1, sent = 0, frame = 0;
    std::string line;  // the whole answer (the ground robot's `topics`)
};

class Synced {  // a driver that follows the simulator's time (Mavlink, Camera, ros2)
public:
    virtual ~Synced() = default;
    virtual long long lockstep_sent() const = 0;
    // Wait until the driver holds what `step` says was sent; why not, or "".
    virtual std::string lockstep_sync(long long t_us, const Step& step) = 0;
    // Over ROS 2 (the ground robot): the resolved topics the hello names,
    virtual void lockstep_topics(std::vector<std::string>& /*subscribe*/,
                                 std::vector<std::string>& /*publish*/) const {}
    // what to do once the simulator has answered the hello (why not, or ""),
    virtual std::string lockstep_started(const std::string& /*hello*/) { return std::string(); }
    // and the samples published on each topic since connecting, for `next`.
    virtual void lockstep_counts(std::map<std::string, long long>& /*published*/) const {}
    // The run is over: stop reading before the simulator hears goodbye and ends its streams.
    virtual void lockstep_end() {}
};

// The members of an object member `"key":{"a":1,"b":2}` of flat numbers (topic counts).
inline std::map<std::string, long long> counts_member(const std::string& line, const char* key) {
    std::map<std::string, long long> out;
    const std::string k = std::string("\"") + key + "\":{";
    std::size_t at = line.find(k);
    if (at == std::string::npos) return out;
    at += k.size();
    while (at < line.size() && line[at] == '"') {
        const std::size_t close = line.find('"', at + 1);
        if (close == std::string::npos || close + 1 >= line.size() || line[close + 1] != ':') break;
        const std::string name = line.substr(at + 1, close - at - 1);
        const char* p = line.c_str() + close + 2;
        char* end = nullptr;
        const long long v = std::strtoll(p, &end, 10);
        if (end == p) break;
        out[name] = v;
        at = static_cast<std::size_t>(end - line.c_str());
        if (at < line.size() && line[at] == ',') ++at;
    }
    return out;
}

// The strings of an array member `"key":["a","b"]` (topic names: no escapes).
inline std::vector<std::string> names_member(const std::string& line, const char* key) {
    std::vector<std::string> out;
    const std::string k = std::string("\"") + key + "\":[";
    std::size_t at = line.find(k);
    if (at == std::string::npos) return out;
    at += k.size();
    while (at < line.size() && line[at] == '"') {
        const std::size_t close = line.find('"', at + 1);
        if (close == std::string::npos) break;
        out.push_back(line.substr(at + 1, close - at - 1));
        at = close + 1;
        if (at < line.size() && line[at] == ',') ++at;
    }
    return out;
}

// A number member `"key":123` of one of the simulator's lines (flat JSON objects).
inline bool member(const std::string& line, const char* key, long long* out) {
    const std::string k = std::string("\"") + key + "\":";
    const std::size_t at = line.find(k);
    if (at == std::string::npos) return false;
    const char* p = line.c_str() + at + k.size();
    char* end = nullptr;
    errno = 0;
    const long long v = std::strtoll(p, &end, 10);
    if (end == p || errno != 0 || (*end != ',' && *end != '}')) return false;
    *out = v;
    return true;
}

// A string member `"key":"text"` (no escapes but \" kept as is), or "" when absent.
inline std::string text_member(const std::string& line, const char* key, bool* found = nullptr) {
    const std::string k = std::string("\"") + key + "\":\"";
    const std::size_t at = line.find(k);
    if (found) *found = at != std::string::npos;
    if (at == std::string::npos) return "";
    std::size_t end = at + k.size();
    while (end < line.size() && !(line[end] == '"' && line[end - 1] != '\\')) ++end;
    return line.substr(at + k.size(), end - at - k.size());
}

inline std::string json_text(const std::string& s) {
    std::string out = "\"";
    for (char c : s) {
        if (c == '"' || c == '\\') out += '\\';
        if (static_cast<unsigned char>(c) >= 0x20) out += c;
    }
    return out + "\"";
}

inline std::string json_list(const std::vector<std::string>& items) {
    std::string out;
    for (const std::string& s : items) out += (out.empty() ? "" : ",") + json_text(s);
    return "[" + out + "]";
}

class Client {
public:
    // `sim`, `sim:PORT` or `sim:HOST:PORT`: throws std::invalid_argument otherwise.
    explicit Client(const std::string& text) : text_(text) {
        const std::size_t colon = text.find(':');
        if (text.substr(0, colon) != "sim")
            throw std::invalid_argument("--clock " + text + ": expected real, virtual or sim[:[HOST:]PORT]");
        if (colon == std::string::npos) return;
        const std::string rest = text.substr(colon + 1);
        const std::size_t last = rest.rfind(':');
        const std::string port = last == std::string::npos ? rest : rest.substr(last + 1);
        if (last != std::string::npos && last > 0) host_ = rest.substr(0, last);
        const bool digits = !port.empty() && port.size() <= 5 &&
                            std::all_of(port.begin(), port.end(), [](char c) { return c >= '0' && c <= '9'; });
        if (!digits || std::atoi(port.c_str()) < 1 || std::atoi(port.c_str()) > 65535)
            throw std::invalid_argument("--clock " + text + ": expected sim:PORT or sim:HOST:PORT");
        port_ = std::atoi(port.c_str());
    }
    ~Client() {
        if (fd_ >= 0) ::close(fd_);
    }
    Client(const Client&) = delete;
    Client& operator=(const Client&) = delete;

    long long reached() const { return t_; }           // -1 before the first step
    long long now_us() const { return t_ < 0 ? 0 : t_; }  // simulated µs
    void add(Synced* d) { drivers_.push_back(d); }
    void remove(Synced* d) { drivers_.erase(std::remove(drivers_.begin(), drivers_.end(), d), drivers_.end()); }
    bool gone() const { return !gone_.empty(); }

    // Reach the simulator and say hello; Gone when it cannot be had.
    void connect(const std::string& name) {
        const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(kConnectWaitS);
        bool told = false;
        for (;;) {
            std::string why = try_connect();
            if (why.empty()) break;
            if (std::chrono::steady_clock::now() > end)
                throw Gone("no simulator at " + host_ + ":" + std::to_string(port_) + " (" + why +
                           "); start `hfsmc sim --lockstep PORT` first");
            if (!told) {
                told = true;
                const std::string line = name + ": waiting for the simulator at " + host_ + ":" +
                                         std::to_string(port_) + "\n";
                std::fwrite(line.data(), 1, line.size(), stderr);
            }
            std::this_thread::sleep_for(std::chrono::milliseconds(200));
        }
        std::vector<std::string> subscribe, publish;
        for (const Synced* d : drivers_) d->lockstep_topics(subscribe, publish);
        std::string topics;
        if (!subscribe.empty() || !publish.empty()) {  // over ROS 2: the resolved topics
            topics = ",\"subscribe\":" + json_list(subscribe) + ",\"publish\":" + json_list(publish);
        }
        send(std::string("{\"hello\":\"") + kProtocol + "\",\"version\":" + std::to_string(kVersion) +
             ",\"component\":" + json_text(name) + topics + "}");
        const std::string hello = read();
        long long version = 0;
        if (text_member(hello, "hello") != kProtocol || !member(hello, "version", &version) ||
            version != kVersion)
            throw Gone(host_ + ":" + std::to_string(port_) +
                       " is not an hfsmc simulator in lockstep (it said " + hello.substr(0, 80) + ")");
        for (Synced* d : drivers_) {
            const std::string problem = d->lockstep_started(hello);
            if (!problem.empty()) throw Gone(problem);
        }
    }

    // Everything before t_us is done: step the simulator to it and wait until the drivers
    // hold what it sent. Gone when it is gone.
    void advance(long long t_us) {
        if (!gone_.empty()) throw Gone(gone_);
        try {
            long long sent = 0;
            for (const Synced* d : drivers_) sent += d->lockstep_sent();
            std::map<std::string, long long> published;
            for (const Synced* d : drivers_) d->lockstep_counts(published);
            std::string topics;
            for (const auto& kv : published)
                topics += (topics.empty() ? "" : ",") + json_text(kv.first) + ":" + std::to_string(kv.second);
            send("{\"next\":" + std::to_string(t_us) + ",\"sent\":" + std::to_string(sent) +
                 (published.empty() ? std::string() : ",\"topics\":{" + topics + "}") + "}");
            const std::string line = read();
            bool bye = false;
            const std::string why = text_member(line, "bye", &bye);
            if (bye) throw Gone("the simulator has stopped (" + why + ")");
            Step step;
            step.line = line;
            if (!member(line, "t", &step.t) || step.t != t_us || !member(line, "sent", &step.sent) ||
                !member(line, "frame", &step.frame))
                throw Gone("the simulator broke the protocol: " + line.substr(0, 80));
            t_ = t_us;
            for (Synced* d : drivers_) {
                const std::string problem = d->lockstep_sync(t_us, step);
                if (!problem.empty()) throw Gone(problem);
            }
        } catch (const Gone& e) {
            gone_ = e.what();
            throw;
        }
    }

    // Say goodbye (the simulator stops or goes on in real time, as it was told).
    void close(const std::string& why) {
        if (fd_ < 0) return;
        for (Synced* d : drivers_) d->lockstep_end();
        if (gone_.empty()) {
            try {
                send("{\"bye\":" + json_text(why) + "}");
            } catch (const Gone&) {
            }
        }
        ::close(fd_);
        fd_ = -1;
    }

private:
    std::string try_connect() {
        addrinfo hints{};
        hints.ai_family = AF_INET;
        hints.ai_socktype = SOCK_STREAM;
        addrinfo* found = nullptr;
        if (::getaddrinfo(host_.c_str(), std::to_string(port_).c_str(), &hints, &found) != 0 || !found)
            return "unknown host";
        const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
        const int ok = fd < 0 ? -1 : ::connect(fd, found->ai_addr, found->ai_addrlen);
        const int err = errno;
        ::freeaddrinfo(found);
        if (ok != 0) {
            if (fd >= 0) ::close(fd);
            return std::strerror(err);
        }
        const int one = 1;
        ::setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
        fd_ = fd;
        return "";
    }

    void send(const std::string& line) {
        const std::string data = line + "\n";
        std::size_t done = 0;
        while (done < data.size()) {
            const ssize_t n = ::send(fd_, data.data() + done, data.size() - done, MSG_NOSIGNAL);
            if (n < 0 && errno == EINTR) continue;
            if (n <= 0) throw Gone("the simulator has gone (its connection is closed)");
            done += static_cast<std::size_t>(n);
        }
    }

    std::string read() {
        const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(kAnswerWaitS);
        std::size_t nl;
        while ((nl = buf_.find('\n')) == std::string::npos) {
            const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
                end - std::chrono::steady_clock::now()).count();
            if (left <= 0) {
                char text[96];
                std::snprintf(text, sizeof text, "the simulator has not answered for %g s", kAnswerWaitS);
                throw Gone(text);
            }
            pollfd p{fd_, POLLIN, 0};
            const int r = ::poll(&p, 1, static_cast<int>(std::min<long long>(left, 1000)));
            if (r <= 0) continue;  // a signal, or no answer yet
            char chunk[4096];
            const ssize_t n = ::recv(fd_, chunk, sizeof chunk, 0);
            if (n < 0 && errno == EINTR) continue;
            if (n <= 0) throw Gone("the simulator has gone (its connection is closed)");
            buf_.append(chunk, static_cast<std::size_t>(n));
        }
        std::string line = buf_.substr(0, nl);
        buf_.erase(0, nl + 1);
        if (line.empty() || line.front() != '{' || line.back() != '}')
            throw Gone("the simulator broke the protocol: " + line.substr(0, 60));
        return line;
    }

    std::string text_;
    std::string host_ = "127.0.0.1";
    int port_ = kDefaultPort;
    int fd_ = -1;
    long long t_ = -1;
    std::string buf_, gone_;
    std::vector<Synced*> drivers_;
};

// The clock of this process with --clock sim (set before the interfaces are made).
inline Client*& current() {
    static Client* c = nullptr;
    return c;
}

}  // namespace simclock
}  // namespace hfsmc
