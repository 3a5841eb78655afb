// hfsmc_mavlink_link.cpp: the link of the `mavlink` interface (hfsmc/mavlink.hpp),
// compiled into the library hfsmc_mavlink beside hfsmc_mavlink.cpp: the options, the
// socket the URL names, the reader thread the driver base owns (or, in lockstep, the same
// work on the automaton's thread at simulated time), the MAVLink parser, duplicates and
// the link's watch.
//
// The mavgen headers are included with -Waddress-of-packed-member (they take
// the address of packed fields everywhere) and -Wpedantic (anonymous structs)
// off: g++ 12 gives them no other warning with -Wall -Wextra, so they build with
// -Werror whether the include folder is given with -I or -isystem.
#include <arpa/inet.h>
#include <fcntl.h>
#include <netdb.h>
#include <netinet/in.h>
#include <poll.h>
#include <pthread.h>
#include <signal.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <initializer_list>
#include <limits>
#include <map>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Waddress-of-packed-member"
#pragma GCC diagnostic ignored "-Wpedantic"
#include "mavlink/ardupilotmega/mavlink.h"
#pragma GCC diagnostic pop

#include "hfsmc/mavlink.hpp"

namespace hfsmc {

struct Mavlink::Wire {  // under link_
  sockaddr_in peer{};
  mavlink_message_t rx_msg{};
  mavlink_status_t rx_status{};
  mavlink_status_t tx_status{};
};

Mavlink::Mavlink(const std::string& name, const std::string& url,
                 const std::map<std::string, std::string>& options)
    : Driver("mavlink", name, url.empty() ? kDefaultUrl : url, options, {},
              Policy{false, false, true}),  // its own options, its own view (the vehicle)
      sim_(simclock::current()), start_(now()), wire_(std::make_unique<Wire>()) {
  rate_ = positive_option("rate", kFastRateHz);
  ack_timeout_ = positive_option("ack_timeout", kAckTimeoutS);
  double sysid = std::trunc(positive_option("source_system", 255.0));
  if (sysid < 1 || sysid > 255) {
    say("option source_system: " + fmt(sysid) + " is not 1..255, 255 used");
    sysid = 255;
  }
  sysid_ = static_cast<uint8_t>(sysid);
  auto chosen = options.find("autopilot");
  if (chosen != options.end()) {
    autopilot_ = chosen->second;
    for (char& c : autopilot_) c = static_cast<char>(c >= 'A' && c <= 'Z' ? c - 'A' + 'a' : c);
    if (autopilot_ != "auto" && autopilot_ != "ardupilot" && autopilot_ != "px4") {
      say("option autopilot: `" + autopilot_ + "` is not auto, ardupilot or px4; auto used");
      autopilot_ = "auto";
    }
  }
  px4_ = autopilot_ == "px4";  // else known from the first heartbeat
  for (const auto& kv : options) {
    if (kv.first != "rate" && kv.first != "ack_timeout" && kv.first != "source_system" &&
        kv.first != "autopilot") {
      say("unknown option `" + kv.first +
          "` ignored (options: rate, ack_timeout, source_system, autopilot)");
    }
  }
  offboard_ = std::make_unique<px4::Offboard>(
      [this](const px4::Target& t) { send_target(t); },
      [this] {
        Pending p{"set_mode", "set_mode GUIDED (OFFBOARD)", MAV_CMD_DO_SET_MODE, {0, 0, 0, 0, 0, 0, 0},
                  {}, {}, true, false};
        px4::set_mode_params(px4::kOffboard, &p.params[0], &p.params[1], &p.params[2]);
        send_long(p);
      },
      [this](const std::string& line) { say(line); });
  if (!live()) return;  // a fake fed from the inputs (the base has checked every entry)
  std::string why = open_socket();
  if (!why.empty()) {
    say("cannot open " + this->url() + ": " + why);
    std::exit(1);
  }
  if (simclock::Client* sim = join_lockstep()) {  // lockstep: no reader thread
    sim_ = sim;
  } else {
    start_thread([this] { run(); });
  }
  register_feed(this);
}

Mavlink::Clock::time_point Mavlink::now() const {
  if (sim_ == nullptr) return Clock::now();
  return Clock::time_point(std::chrono::duration_cast<Clock::duration>(
      std::chrono::microseconds(sim_->now_us())));
}

/// Lockstep, before the instant at t_us: read until the simulator's `sent` datagrams
/// have come, then do the reader's timed work; why not, or "".
std::string Mavlink::lockstep_sync(long long, const simclock::Step& step) {
  const auto end = Clock::now() + duration(kDatagramWaitS);
  for (;;) {
    drain();
    if (received_ >= step.sent) break;
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(end - Clock::now()).count();
    if (left <= 0)
      return name() + ": " + std::to_string(step.sent - received_) +
             " of the simulator's datagrams did not come in " + fmt(kDatagramWaitS) + " s (is " + url() +
             " the simulator's link?)";
    pollfd pfd{fd_, POLLIN, 0};
    ::poll(&pfd, 1, static_cast<int>(std::min<long long>(left, kPollMs)));
  }
  timed(now());
  return "";
}

Mavlink::~Mavlink() {
  leave_lockstep();
  unregister_source(this);
  unregister_feed(this);
  close();
}

/// Stop the reader and close the socket (also done by the destructor).
void Mavlink::close() {
  stop();  // the base's: the reader wakes within kPollMs
  std::lock_guard<std::mutex> lock(link_);
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
}

mavlink_status_t* Mavlink::tx_status() { return &wire_->tx_status; }  // under link_

void Mavlink::send(const mavlink_message_t& msg) {  // under link_
  if (fd_ < 0 || !peer_known_) return;  // udpin: nobody has written to us yet
  uint8_t buf[MAVLINK_MAX_PACKET_LEN];
  uint16_t len = mavlink_msg_to_send_buffer(buf, &msg);
  // A full buffer or an unreachable peer loses the datagram, as UDP does.
  if (::sendto(fd_, buf, len, MSG_DONTWAIT, reinterpret_cast<const sockaddr*>(&wire_->peer),
               sizeof wire_->peer) >= 0)
    ++sent_;
}

// -- the reader thread -------------------------------------------------------------
void Mavlink::run() {
  while (!stopping()) {
    pollfd pfd{fd_, POLLIN, 0};
    int n = ::poll(&pfd, 1, kPollMs);
    if (n > 0 && (pfd.revents & POLLIN)) drain();
    timed(Clock::now());
  }
}

/// The reader's timed work: our heartbeat, resends and deadlines, the link's watch.
void Mavlink::timed(Clock::time_point now) {
  if (!heartbeat_sent_ || now >= next_heartbeat_) {
    heartbeat_sent_ = true;
    next_heartbeat_ = now + duration(kGcsHeartbeatS);
    std::lock_guard<std::mutex> lock(link_);
    mavlink_message_t msg;
    mavlink_msg_heartbeat_pack_status(sysid_, kGcsComponent, &wire_->tx_status, &msg, MAV_TYPE_GCS,
                                      MAV_AUTOPILOT_INVALID, 0, 0, 0);
    send(msg);
  }
  expire(now);
  upload_tick(now);
  watch_link();
  if (px4()) {
    uint32_t mode;
    bool armed;
    double heartbeat_at = -std::numeric_limits<double>::infinity();
    {
      std::lock_guard<std::mutex> lock(state_);
      mode = s_.custom_mode;
      armed = s_.base_mode & MAV_MODE_FLAG_SAFETY_ARMED;
      if (s_.heartbeat_seen) heartbeat_at = seconds(s_.heartbeat_at.time_since_epoch());
    }
    bool switch_accepted;
    {
      std::lock_guard<std::mutex> lock(link_);
      auto it = acks_.find("set_mode");
      switch_accepted = it != acks_.end() && it->second == "accepted";
    }
    offboard_->tick(now_s(), mode, armed, heartbeat_at, switch_accepted);
  }
}

/// Handle every datagram waiting (at most 1000, so a flood cannot starve the
/// deadlines); bytes that are no MAVLink frame are dropped, never raised.
void Mavlink::drain() {
  std::vector<uint8_t>& buf = rx_buf_;
  std::vector<mavlink_message_t> got;
  for (int i = 0; i < 1000; ++i) {
    sockaddr_in from{};
    socklen_t from_len = sizeof from;
    ssize_t n = ::recvfrom(fd_, buf.data(), buf.size(), MSG_DONTWAIT,
                           reinterpret_cast<sockaddr*>(&from), &from_len);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) break;
    if (n < 0) continue;  // an ICMP error reported on the socket: try the next datagram
    ++received_;
    got.clear();
    {
      std::lock_guard<std::mutex> lock(link_);
      wire_->rx_status.parse_state = MAVLINK_PARSE_STATE_IDLE;  // each datagram from scratch
      for (ssize_t k = 0; k < n; ++k) {
        mavlink_message_t msg;
        mavlink_status_t status;
        if (mavlink_frame_char_buffer(&wire_->rx_msg, &wire_->rx_status, buf[k], &msg, &status) ==
            MAVLINK_FRAMING_OK) {
          got.push_back(msg);
        }
      }
      if (!got.empty() && listening_ && from_len == sizeof from) {
        wire_->peer = from;  // answer whoever speaks MAVLink to us, as mavutil's udpin does
        peer_known_ = true;
      }
    }
    for (const mavlink_message_t& msg : got) handle(msg);
  }
}

/// A copy of one of the last kDuplicateWindow frames of that source (same seq,
/// message and checksum): a network duplicate, however late. Reader thread only.
bool Mavlink::duplicate(const mavlink_message_t& msg) {
  const Clock::time_point now = this->now();
  Recent& r = recent_[static_cast<uint16_t>(msg.sysid << 8 | msg.compid)];
  if (!r.any || seconds(now - r.at) > kSilenceS) r = Recent{};  // first word, or a reboot
  r.any = true;
  r.at = now;
  const uint64_t key = static_cast<uint64_t>(msg.seq) << 40 |
                       static_cast<uint64_t>(msg.msgid) << 16 | msg.checksum;
  if (r.count.count(key) != 0) return true;
  r.order.push_back(key);
  ++r.count[key];
  if (r.order.size() > kDuplicateWindow) {
    auto it = r.count.find(r.order.front());
    if (--it->second == 0) r.count.erase(it);
    r.order.pop_front();
  }
  return false;
}

void Mavlink::watch_link() {  // the reader thread: the state at hand, not the automaton's snapshot
  bool seen;
  double age;
  {
    std::lock_guard<std::mutex> lock(state_);
    seen = s_.heartbeat_seen;
    age = seen ? seconds(now() - s_.heartbeat_at) : kInf;
  }
  if (!lost_ && seen && !(age < kLinkTimeoutS)) {
    lost_ = true;
    {
      std::lock_guard<std::mutex> lock(state_);
      s_.gps_fix = 0;  // whatever answers next says afresh whether it is ready
      s_.ekf_flags = 0;
    }
    say("link lost: no heartbeat for " + fmt(kLinkTimeoutS) + " s");
  }
}

// -- opening -------------------------------------------------------------------------
/// Open the socket the URL names; "" or why not.
std::string Mavlink::open_socket() {
  std::string kind, rest;
  size_t colon = url().find(':');
  if (colon != std::string::npos) {
    kind = url().substr(0, colon);
    rest = url().substr(colon + 1);
  }
  if (kind == "udp") kind = "udpin";
  size_t last = rest.rfind(':');
  std::string host = last == std::string::npos ? "" : rest.substr(0, last);
  std::string port = last == std::string::npos ? "" : rest.substr(last + 1);
  bool digits = !port.empty() && port.size() <= 5 &&
                std::all_of(port.begin(), port.end(), [](char c) { return c >= '0' && c <= '9'; });
  if ((kind != "udpin" && kind != "udpout") || host.empty() || !digits ||
      std::stoi(port) > 65535 || (kind == "udpout" && std::stoi(port) == 0)) {
    return "expected udpin:HOST:PORT, udpout:HOST:PORT or udp:HOST:PORT";
  }
  addrinfo hints{};
  hints.ai_family = AF_INET;
  hints.ai_socktype = SOCK_DGRAM;
  addrinfo* found = nullptr;
  int err = ::getaddrinfo(host.c_str(), port.c_str(), &hints, &found);
  if (err != 0 || found == nullptr) return std::string("host ") + host + ": " + gai_strerror(err);
  sockaddr_in addr{};
  std::memcpy(&addr, found->ai_addr, sizeof addr);
  ::freeaddrinfo(found);
  fd_ = ::socket(AF_INET, SOCK_DGRAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
  if (fd_ < 0) return std::strerror(errno);
  listening_ = kind == "udpin";
  if (listening_) {
    if (::bind(fd_, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0) {
      std::string why = std::strerror(errno);
      ::close(fd_);
      fd_ = -1;
      return why;
    }
  } else {
    wire_->peer = addr;
    peer_known_ = true;
  }
  return "";
}

// -- helpers -----------------------------------------------------------------------
double Mavlink::positive_option(const std::string& key, double fallback) const {
  auto it = options().find(key);
  if (it == options().end()) return fallback;
  const std::string& raw = it->second;
  std::string text = strip(raw);
  char* end = nullptr;
  errno = 0;
  double value = text.empty() ? -1.0 : std::strtod(text.c_str(), &end);
  if (!text.empty() && (end == nullptr || *end != '\0')) value = -1.0;
  if (!(value > 0) || std::isinf(value)) {
    say("option " + key + ": `" + raw + "` is not a positive number, " + fmt(fallback) +
        " used");
    return fallback;
  }
  return value;
}

}  // namespace hfsmc
