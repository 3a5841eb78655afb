// hfsmc_camera.cpp: the `camera` interface of C++ components (hfsmc/camera.hpp declares
// it and says how it works), compiled once into the library hfsmc_camera. Copied
// unchanged into every component folder that uses it.
#include <netdb.h>
#include <poll.h>
#include <pthread.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/core/utils/logger.hpp>
#include <opencv2/imgcodecs.hpp>  // linked through videoio, which depends on it
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include "hfsmc/camera.hpp"
#include "hfsmc/base64.hpp"
#include "hfsmc/mcap.hpp"  // crc32

namespace hfsmc {

namespace {

#ifdef __linux__
constexpr int kDeviceApi = cv::CAP_V4L2;
#else
constexpr int kDeviceApi = cv::CAP_ANY;
#endif

/// OpenCV's warnings off while a capture opens (unless OPENCV_LOG_LEVEL is set).
/// The log level is global: grabbers share the lowering.
class Quiet {
 public:
  Quiet() : active_(std::getenv("OPENCV_LOG_LEVEL") == nullptr) {
    if (!active_) return;
    std::lock_guard<std::mutex> lock(mutex());
    if (depth()++ == 0) {
      saved() = cv::utils::logging::setLogLevel(cv::utils::logging::LOG_LEVEL_ERROR);
    }
  }
  ~Quiet() {
    if (!active_) return;
    std::lock_guard<std::mutex> lock(mutex());
    if (--depth() == 0) cv::utils::logging::setLogLevel(saved());
  }
  Quiet(const Quiet&) = delete;
  Quiet& operator=(const Quiet&) = delete;

 private:
  static std::mutex& mutex() {
    static std::mutex m;
    return m;
  }
  static int& depth() {
    static int d = 0;
    return d;
  }
  static cv::utils::logging::LogLevel& saved() {
    static cv::utils::logging::LogLevel s = cv::utils::logging::LOG_LEVEL_WARNING;
    return s;
  }
  bool active_;
};

}  // namespace

struct Camera::Grabber {
  std::string name, url;
  cv::Size size;  // empty: frames kept as they come
  std::mutex mutex;  // guards what follows
  std::condition_variable wake;
  cv::Mat latest;
  cv::Mat latest_jpeg;  // its JPEG as the stream sent it; empty when none
  bool no_raw = false;  // the stream's packets are no JPEGs (grabber only)
  Clock::time_point at{};
  long count = 0;
  cv::Mat seen;  // the latest frame a snippet obtained, and its number
  long seen_count = 0;
  bool stop = false;
  bool finished = false;
  bool down = false;  // said on stderr that the stream is down (grabber only)
  bool stamped = false;  // lockstep: the simulator's MJPEG read here, with X-Frame, X-Time-Us
  long long latest_us = 0;  // lockstep: the simulated time the latest frame was rendered for

  bool stopping() {
    std::lock_guard<std::mutex> lock(mutex);
    return stop;
  }

  void pause(double s) {  // wait, or less when asked to stop
    std::unique_lock<std::mutex> lock(mutex);
    wake.wait_for(lock, std::chrono::duration<double>(s), [this] { return stop; });
  }

  void run() {
    double pause_s = kBackoffMinS;
    while (!stopping()) {
      bool got;
      if (stamped) {
        got = read_stamped();
      } else {
        std::unique_ptr<cv::VideoCapture> cap = open();
        got = cap && grab(*cap);
        if (cap) cap->release();
      }
      if (stopping()) return;
      if (got) pause_s = kBackoffMinS;
      if (!down) {
        down = true;
        bool any;
        {
          std::lock_guard<std::mutex> lock(mutex);
          any = count > 0;
        }
        say(std::string("stream ") + (got || any ? "lost" : "not available") + " at " + url +
            ": reconnecting");
      }
      pause(pause_s);
      pause_s = std::min(pause_s * 2, kBackoffMaxS);
    }
  }

  std::unique_ptr<cv::VideoCapture> open() {
    Quiet quiet;  // a failed open warns each retry; the drop is said once by us
    std::unique_ptr<cv::VideoCapture> cap;
    try {
      if (is_number(url)) {  // a device: V4L2 (any backend would also probe USB and more)
        cap = std::make_unique<cv::VideoCapture>(std::atoi(url.c_str()), kDeviceApi);
      } else if (exists(url)) {
        cap = std::make_unique<cv::VideoCapture>(url);
      } else {  // a network stream: bounded waits, so a dead server is noticed
        cap = std::make_unique<cv::VideoCapture>(
            url, cv::CAP_FFMPEG,
            std::vector<int>{cv::CAP_PROP_OPEN_TIMEOUT_MSEC, kOpenTimeoutMs,
                             cv::CAP_PROP_READ_TIMEOUT_MSEC, kReadTimeoutMs});
      }
    } catch (const cv::Exception&) {
      return nullptr;
    }
    if (!cap->isOpened()) return nullptr;
    return cap;
  }

  /// Read frames until the stream ends; whether any came.
  bool grab(cv::VideoCapture& cap) {
    double fps = exists(url) ? cap.get(cv::CAP_PROP_FPS) : 0.0;
    double step = fps > 0 && fps < 1000 ? 1.0 / fps : 0.0;  // a file plays at its rate
    // A network stream is read as its packets (an MJPEG stream's are JPEGs) and decoded
    // here: a recording keeps the JPEG as it came, the lossless source of the pixels.
    bool raw = false;
    if (!no_raw && !exists(url) && !is_number(url)) {
      try {
        raw = cap.set(cv::CAP_PROP_FORMAT, -1);
      } catch (const cv::Exception&) {
        raw = false;
      }
    }
    bool got = false;
    while (!stopping()) {
      cv::Mat img;  // a fresh one each time: a frame handed out is never overwritten
      cv::Mat jpeg;
      bool ok;
      try {
        if (raw) {
          cv::Mat packet;
          ok = cap.read(packet);
          if (ok && packet.total() * packet.elemSize() >= 2 && packet.ptr()[0] == 0xFF &&
              packet.ptr()[1] == 0xD8) {
            jpeg = packet.reshape(1, 1).clone();
            img = cv::imdecode(jpeg, cv::IMREAD_COLOR);
          } else if (ok) {
            no_raw = true;  // not JPEG packets: decoded by the capture from the next open
            return got;
          }
        } else {
          ok = cap.read(img);
        }
      } catch (const cv::Exception&) {
        ok = false;
      }
      if (!ok || img.empty()) return got;
      if (!size.empty() && img.size() != size) {
        cv::Mat small;
        cv::resize(img, small, size, 0, 0, cv::INTER_AREA);
        img = small;
        jpeg = cv::Mat();  // resized: recorded as PNG
      }
      {
        std::lock_guard<std::mutex> lock(mutex);
        latest_jpeg = jpeg;
        latest = img;
        at = Clock::now();
        ++count;
      }
      if (!got) {
        got = true;
        if (down && !stopping()) {
          down = false;
          say("stream back at " + url);
        }
      }
      if (step > 0) pause(step);
    }
    return got;
  }

  // -- lockstep: the simulator's MJPEG parts and their stamps ------------------------
  struct Http {  // one connection, read a line or a number of bytes at a time, bounded
    int fd = -1;
    std::string buf;
    Grabber* g = nullptr;
    ~Http() {
      if (fd >= 0) ::close(fd);
    }
    bool fill() {
      pollfd p{fd, POLLIN, 0};
      for (int waited = 0; waited < kReadTimeoutMs; waited += 100) {
        if (g->stopping()) return false;
        if (::poll(&p, 1, 100) > 0) {
          char chunk[65536];
          const ssize_t n = ::recv(fd, chunk, sizeof chunk, 0);
          if (n <= 0) return false;
          buf.append(chunk, static_cast<std::size_t>(n));
          return true;
        }
      }
      return false;
    }
    bool line(std::string& out) {
      std::size_t nl;
      while ((nl = buf.find('\n')) == std::string::npos)
        if (buf.size() > 8192 || !fill()) return false;
      out = buf.substr(0, nl);
      if (!out.empty() && out.back() == '\r') out.pop_back();
      buf.erase(0, nl + 1);
      return true;
    }
    bool bytes(std::size_t n, std::string& out) {
      while (buf.size() < n)
        if (!fill()) return false;
      out = buf.substr(0, n);
      buf.erase(0, n);
      return true;
    }
  };

  /// One connection's frames until it ends; whether any came.
  bool read_stamped() {
    const std::string rest = url.substr(7);  // after http://
    const std::size_t slash = rest.find('/');
    const std::string where = rest.substr(0, slash);
    const std::string path = slash == std::string::npos ? "/" : rest.substr(slash);
    const std::size_t colon = where.rfind(':');
    const std::string host = where.substr(0, colon);
    const std::string port = colon == std::string::npos ? "80" : where.substr(colon + 1);
    addrinfo hints{};
    hints.ai_family = AF_INET;
    hints.ai_socktype = SOCK_STREAM;
    addrinfo* found = nullptr;
    if (::getaddrinfo(host.c_str(), port.c_str(), &hints, &found) != 0 || !found) return false;
    Http h;
    h.g = this;
    h.fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    const bool connected = h.fd >= 0 && ::connect(h.fd, found->ai_addr, found->ai_addrlen) == 0;
    ::freeaddrinfo(found);
    if (!connected) return false;
    const std::string request = "GET " + path + " HTTP/1.0\r\nHost: " + where + "\r\n\r\n";
    if (::send(h.fd, request.data(), request.size(), MSG_NOSIGNAL) != static_cast<ssize_t>(request.size()))
      return false;
    std::string text;
    if (!h.line(text) || text.find(" 200") == std::string::npos) return false;
    while (h.line(text) && !text.empty()) {
    }
    bool got = false;
    while (!stopping()) {
      long long length = -1, number = 0, t_us = 0;
      do {
        if (!h.line(text)) return got;
      } while (text.empty() || text.rfind("--", 0) == 0);
      do {
        const std::size_t c = text.find(':');
        if (c == std::string::npos) continue;
        std::string key = text.substr(0, c);
        for (char& ch : key) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
        const long long value = std::atoll(text.c_str() + c + 1);
        if (key == "content-length") length = value;
        else if (key == "x-frame") number = value;
        else if (key == "x-time-us") t_us = value;
      } while (h.line(text) && !text.empty());
      if (length < 0) return got;  // not the simulator's stream
      std::string data;
      if (!h.bytes(static_cast<std::size_t>(length), data)) return got;
      if (number <= 0) continue;  // a frame without its stamp: the next will do
      cv::Mat jpeg = cv::Mat(1, static_cast<int>(data.size()), CV_8UC1,
                             const_cast<char*>(data.data())).clone();
      cv::Mat img;
      try {
        img = cv::imdecode(jpeg, cv::IMREAD_COLOR);
      } catch (const cv::Exception&) {
      }
      if (img.empty()) continue;  // a damaged frame: the next will do
      if (!size.empty() && img.size() != size) {
        cv::Mat small;
        cv::resize(img, small, size, 0, 0, cv::INTER_AREA);
        img = small;
        jpeg = cv::Mat();  // resized: recorded as PNG
      }
      {
        std::lock_guard<std::mutex> lock(mutex);
        latest_jpeg = jpeg;
        latest = img;
        latest_us = t_us;
        count = static_cast<long>(number);
        wake.notify_all();
      }
      if (!got) {
        got = true;
        if (down && !stopping()) {
          down = false;
          say("stream back at " + url);
        }
      }
    }
    return got;
  }

  void say(const std::string& text) const {
    std::string line = name + ": " + text + "\n";
    std::fwrite(line.data(), 1, line.size(), stderr);  // one write: lines never interleave
    std::fflush(stderr);
  }
};

Camera::Camera(const std::string& name, const std::string& url,
               const std::map<std::string, std::string>& options)
    : Driver("camera", name, url.empty() ? kDefaultUrl : url, options, {{"size", ""}},
             Policy{true, false}),
      g_(std::make_shared<Grabber>()) {
  // FFmpeg's own messages (connection refused, ...) at every retry would drown
  // ours; it reads this when first used, so before any capture opens.
  ::setenv("OPENCV_FFMPEG_LOGLEVEL", "-8", 0);  // AV_LOG_QUIET, unless set
  g_->name = name;
  g_->url = Driver::url();
  given_ = options;
  for (const auto& kv : options) {
    int w = 0, h = 0;
    if (kv.first == "size" && parse_size(kv.second, &w, &h)) {
      g_->size = cv::Size(w, h);
    } else if (kv.first == "size") {
      g_->say("option size: `" + kv.second +
              "` is not WxH (320x240): frames kept as they come");
    } else {
      g_->say("unknown option `" + kv.first + "` ignored (options: size)");
    }
  }
  if (!live()) {  // a fake fed from the inputs (the base has checked every entry)
    register_feed(this);
    return;
  }
  if (simclock::Client* sim = simclock::current()) {  // lockstep: stamped frames
    if (g_->url.rfind("http://", 0) != 0) {
      g_->say("--clock sim needs the simulator's MJPEG stream (http://...), not " + g_->url);
      std::exit(1);
    }
    sim_ = sim;
    g_->stamped = true;
    sim->add(this);
  }
  std::shared_ptr<Grabber> g = g_;
  thread_ = quiet_thread([g] {
    g->run();
    std::lock_guard<std::mutex> lock(g->mutex);
    g->finished = true;
    g->wake.notify_all();
  });
  register_feed(this);
}

Camera::~Camera() {
  if (sim_ != nullptr && simclock::current() == sim_) sim_->remove(this);
  unregister_source(this);
  unregister_feed(this);
  close();
}

/// The latest frame (H x W, CV_8UC3, BGR); an empty Mat before the first. The
/// same pixels until a newer frame comes: clone it before drawing on it for keeps.
cv::Mat Camera::frame() const {
  const long long count = snap("frame", "frame").count;
  if (count != 0 && count != recorded_) record_frame();
  std::lock_guard<std::mutex> lock(g_->mutex);
  g_->seen = snap_frame_;  // for the monitor's viewers: a header copy
  g_->seen_count = static_cast<long>(count);
  return snap_frame_;
}

std::string Camera::source_config() const {
  std::string options;
  for (const auto& kv : given_)
    options += (options.empty() ? "" : ",") + json_string(kv.first) + ":" + json_string(kv.second);
  return "{\"type\":\"camera\",\"url\":" + json_string(g_->url) + ",\"options\":{" + options + "}}";
}

void Camera::read(CameraSnap& s) {
  if (sim_ != nullptr) {  // lockstep: the frame the simulator named at this instant
    read_frame_ = held_;
    read_jpeg_ = held_jpeg_;
    s.count = held_count_;
    s.age = held_count_ == 0 ? std::numeric_limits<double>::infinity()
                             : static_cast<double>(sim_->now_us() - held_us_) / 1e6;
    return;
  }
  std::lock_guard<std::mutex> lock(g_->mutex);
  read_frame_ = g_->latest;
  read_jpeg_ = g_->latest_jpeg;
  s.count = g_->count;
  s.age = g_->count == 0 ? std::numeric_limits<double>::infinity()
                         : std::chrono::duration<double>(Clock::now() - g_->at).count();
}

void Camera::snapshot_taken() {
  if (live()) {
    snap_frame_ = read_frame_;
    snap_jpeg_ = read_jpeg_;
    return;
  }
  const CameraSnap& fed = current();
  if (fed.file != loaded_) {  // a new picture: read it once (the exact pixels of the PNG)
    loaded_ = fed.file;
    image_ = cv::Mat();
    if (!loaded_.empty()) {
      try {
        image_ = cv::imread(loaded_, cv::IMREAD_COLOR);
      } catch (const cv::Exception&) {
      }
      if (image_.empty()) {
        std::fprintf(stderr, "%s: --playback: %s: cannot read the frame (a PNG or JPEG file)\n",
                     g_->name.c_str(), loaded_.c_str());
        std::exit(2);
      }
      if (fed.crc >= 0 && pixels_crc(image_) != static_cast<std::uint32_t>(fed.crc) && !warned_) {
        warned_ = true;
        std::fprintf(stderr, "%s: frame %ld (%s) decodes to other pixels here than in the recorded run "
                     "(another JPEG decoder): from there on this run does not compute on the recorded "
                     "pixels\n", g_->name.c_str(), static_cast<long>(fed.count), loaded_.c_str());
      }
    }
  }
  snap_frame_ = image_;
}

/// Lockstep, before the instant at t_us: wait until the frame numbered step.frame has
/// come (0: the camera is down, nothing to wait for); why not, or "".
std::string Camera::lockstep_sync(long long, const simclock::Step& step) {
  if (step.frame <= 0) return "";
  std::unique_lock<std::mutex> lock(g_->mutex);
  const bool ok = g_->wake.wait_for(lock, std::chrono::duration<double>(kFrameWaitS),
                                    [&] { return g_->count >= step.frame; });
  if (!ok) {
    char wait[32];
    std::snprintf(wait, sizeof wait, "%g", kFrameWaitS);
    return g_->name + ": the simulator's frame " + std::to_string(step.frame) + " did not come in " +
           wait + " s from " + g_->url;
  }
  held_ = g_->latest;
  held_jpeg_ = g_->latest_jpeg;
  held_count_ = g_->count;
  held_us_ = g_->latest_us;
  return "";
}

/// Stop the grabber (also done by the destructor); waits 1 s at most.
void Camera::close() {
  if (!thread_.joinable()) return;
  std::unique_lock<std::mutex> lock(g_->mutex);
  g_->stop = true;
  g_->wake.notify_all();
  bool done = g_->wake.wait_for(lock, std::chrono::duration<double>(kCloseWaitS),
                                [this] { return g_->finished; });
  lock.unlock();
  if (done) {
    thread_.join();
  } else {
    thread_.detach();  // stuck in a read: it ends on its own, holding its state
  }
}

/// A `frame` message (schemas/monitor.md): the latest frame a snippet obtained with
/// frame(), downscaled to 320 px wide at most, as base64 JPEG; "" when none is new.
std::string Camera::feed_message(long long t_ms) {
  cv::Mat image;
  {
    std::lock_guard<std::mutex> lock(g_->mutex);
    if (g_->seen_count == feed_sent_ || g_->seen.empty()) return "";
    feed_sent_ = g_->seen_count;
    image = g_->seen;
  }
  if (image.cols > kFrameWidth) {
    const int h = std::max(1, static_cast<int>(std::lround(
                                  image.rows * static_cast<double>(kFrameWidth) / image.cols)));
    cv::resize(image, image, cv::Size(kFrameWidth, h), 0, 0, cv::INTER_AREA);
  }
  std::vector<uchar> jpeg;
  try {
    if (!cv::imencode(".jpg", image, jpeg, {cv::IMWRITE_JPEG_QUALITY, kFrameQuality})) return "";
  } catch (const cv::Exception&) {
    return "";
  }
  return "{\"type\":\"frame\",\"t\":" + std::to_string(t_ms) + ",\"name\":" +
         json_string(g_->name) + ",\"width\":" + std::to_string(image.cols) +
         ",\"height\":" + std::to_string(image.rows) + ",\"jpeg\":\"" + base64(jpeg) + "\"}";
}

/// The recording gets the frame of this instant, once (lossless PNG, base64).
void Camera::record_frame() const {
  const long long count = current().count;
  recorded_ = static_cast<long>(count);
  Recorder* r = recorder();
  if (r == nullptr || snap_frame_.empty()) return;
  if (!snap_jpeg_.empty()) {  // the JPEG as it came: no encoding
    const std::vector<uchar> jpeg(snap_jpeg_.ptr(), snap_jpeg_.ptr() + snap_jpeg_.total());
    r->frame(*this, snapshot_t_, static_cast<long>(count), "jpeg", base64(jpeg), pixels_crc(snap_frame_));
    return;
  }
  std::vector<uchar> png;
  try {
    if (!cv::imencode(".png", snap_frame_, png, {cv::IMWRITE_PNG_COMPRESSION, 1})) return;
  } catch (const cv::Exception&) {
    return;
  }
  r->frame(*this, snapshot_t_, static_cast<long>(count), "png", base64(png), pixels_crc(snap_frame_));
}

/// CRC-32 of a frame's pixels, row by row (zlib.crc32 of a numpy array's bytes).
std::uint32_t Camera::pixels_crc(const cv::Mat& m) {
  std::uint32_t crc = 0;
  const std::size_t row = static_cast<std::size_t>(m.cols) * m.elemSize();
  for (int y = 0; y < m.rows; ++y) crc = mcap::crc32(crc, m.ptr(y), row);
  return crc;
}

bool Camera::parse_size(const std::string& text, int* w, int* h) {
  // ^\s*(\d+)\s*[xX]\s*(\d+)\s*$, both non-zero
  size_t i = 0, n = text.size();
  auto spaces = [&] {
    while (i < n && std::isspace(static_cast<unsigned char>(text[i]))) ++i;
  };
  auto number = [&](int* out) {
    size_t start = i;
    long v = 0;
    while (i < n && text[i] >= '0' && text[i] <= '9' && v <= 100000) v = v * 10 + (text[i++] - '0');
    *out = static_cast<int>(v);
    return i > start && (i == n || text[i] < '0' || text[i] > '9');
  };
  spaces();
  if (!number(w)) return false;
  spaces();
  if (i >= n || (text[i] != 'x' && text[i] != 'X')) return false;
  ++i;
  spaces();
  if (!number(h)) return false;
  spaces();
  return i == n && *w > 0 && *h > 0;
}

bool Camera::is_number(const std::string& s) {
  if (s.empty()) return false;
  for (char c : s) {
    if (c < '0' || c > '9') return false;
  }
  return true;
}

bool Camera::exists(const std::string& path) {
  struct stat st;
  return ::stat(path.c_str(), &st) == 0;
}

}  // namespace hfsmc
