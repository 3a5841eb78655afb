// hfsmc: the `camera` interface of C++ components (docs/interfaces.md): the latest
// frame of an OpenCV capture, without blocking the automaton.
//
// The C++ twin of templates/python/hfsmc_camera.py: the same behaviour, the
// same timeouts and the same lines on stderr. The URL is anything
// cv::VideoCapture opens: MJPEG over HTTP (http://127.0.0.1:8554/bottom.mjpg),
// a device number (0), a file (replayed at its frame rate, from the start
// again at its end). A grabber thread reads frames as they come and keeps
// only the latest, with its time, under a mutex held for a copy of a Mat
// header: frame() and age() return at once. Each frame is decoded into a
// fresh Mat, so one handed out is never written again. When the stream drops,
// the grabber says so once on stderr and reconnects with a growing pause
// (0.2 s, doubling up to 2 s); it says so again when frames are back.
//
// The grabber shares its state through a shared_ptr: when closing, the
// destructor waits at most 1 s for it (as the Python driver's join does); a
// grabber stuck in a network read (2 s at most) is then left to finish alone.
//
// The automaton sees one snapshot per instant (docs/recording.md): frame(), age(),
// ok() and count() return what was the latest when the instant began. With --record
// the first frame() of each frame writes it to the recording, losslessly: the JPEG an
// MJPEG stream sent (a network stream is read as its packets, decoded here), else a
// PNG; with
// --playback DIR the camera is a fake fed from DIR/inputs.jsonl (PNG files in DIR).
//
// Options: `size: WxH` resizes every frame (320x240).
//
// It is a driver on hfsmc::Driver (driver.hpp, docs/drivers.md): the base keeps its
// options, takes and records the snapshot of each instant (count, age) and feeds the
// fake from the script (the frame's file and CRC beside the fields: CameraSnap::extra);
// the camera adds its grabber, its frames (the recording's, the monitor's) and the lockstep.
//
// The class is declared here and defined in src/hfsmc_camera.cpp, compiled once into
// the library hfsmc_camera: the component's unit sees only OpenCV's core header.
/* hfsmc driver
# The camera driver's declaration, as a user's C++ driver header carries one
# (docs/drivers.md); tests/test_drivers_api.py compares it with the Python driver's
# (hfsmc_camera.Camera). What each method does: docs/interfaces.md.
kind: camera
class: Camera
doc: The latest frame of a video stream
snapshot: {count: 0, age: .inf}
options: {size: ''}
queries: ["frame()", "age()", "ok()", "count()", "close()"]
*/
#pragma once

#include <chrono>
#include <cstdint>
#include <limits>
#include <map>
#include <memory>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <opencv2/core.hpp>

#include "driver.hpp"
#include "json.hpp"
#include "observer.hpp"
#include "playback.hpp"
#include "record.hpp"
#include "simclock.hpp"
#include "thread.hpp"

namespace hfsmc {

// What the automaton sees of a camera at one instant (hfsmc.camera.Snapshot), and the
// frame a script names beside it.
struct CameraSnap {
  long long count = 0;
  double age = std::numeric_limits<double>::infinity();
  std::string file;  // with --playback: the frame's PNG or JPEG ("": none)
  long long crc = -1;  // the CRC-32 of its pixels in the recorded run (-1: not given)
  static std::vector<Field> fields(CameraSnap& s) { return {{"count", &s.count}, {"age", &s.age}}; }
  static bool extra(CameraSnap& s, const std::string& key, const json::Value& v, int line,
                    const playback::Inputs& in) {
    if (key == "frame") s.file = v.kind == json::Value::NUL ? std::string() : in.frame_file(v, line);
    else if (key == "crc32") s.crc = in.whole(v, "crc32", line);
    return true;  // other fields (`t`, ...) are not part of what the automaton sees
  }
  static long long frame_number(const CameraSnap& s) { return s.count; }
};

class Camera : public Driver<CameraSnap>, public Feed {  // simclock::Synced through the base
 public:
  static constexpr const char* kDefaultUrl = "0";  // the first video device
  static constexpr double kBackoffMinS = 0.2;
  static constexpr double kBackoffMaxS = 2.0;
  static constexpr double kStaleS = 1.0;           // ok() is false when the frame is older
  static constexpr int kOpenTimeoutMs = 3000;      // a network stream that does not answer
  static constexpr int kReadTimeoutMs = 2000;      // a network stream that stops sending
  static constexpr double kCloseWaitS = 1.0;       // the destructor waits that long at most
  static constexpr double kFrameWaitS = 10.0;      // lockstep: the simulator's frame is that late at most
  static constexpr int kFrameWidth = 320;          // frames sent to viewers: at most that wide
  static constexpr int kFrameQuality = 70;         // their JPEG quality

  Camera(const std::string& name, const std::string& url,
         const std::map<std::string, std::string>& options);
  ~Camera() override;

  Camera(const Camera&) = delete;
  Camera& operator=(const Camera&) = delete;

  const std::string& name() const { return Driver::name(); }
  const std::string& url() const { return Driver::url(); }

  /// The latest frame (H x W, CV_8UC3, BGR); an empty Mat before the first. The
  /// same pixels until a newer frame comes: clone it before drawing on it for keeps.
  cv::Mat frame() const;

  /// Seconds since the latest frame arrived; +inf before the first.
  double age() const { return snap("age").age; }

  /// Frames are coming: the latest is less than a second old.
  bool ok() const { return snap("ok", "age").age < kStaleS; }

  /// Frames received so far (a new one since the last tick when it has grown).
  long count() const { return static_cast<long>(snap("count").count); }

  // -- Source: the options as given (the base takes the snapshot) -----------------------
  std::string source_config() const override;
  std::string snapshot_schema() const override { return std::string(); }  // the built-in one

  // -- simclock::Synced: lockstep with `hfsmc sim` (--clock sim) --------------------------
  long long lockstep_sent() const override { return 0; }
  std::string lockstep_sync(long long t_us, const simclock::Step& step) override;
  void lockstep_end() override { close(); }

  /// Stop the grabber (also done by the destructor); waits 1 s at most.
  void close();

 private:
  // -- for the monitor's viewers (Feed: private here, called through the base) -------
  const char* feed_kind() const override { return "camera"; }
  std::string feed_name() const override { return name(); }
  /// A `frame` message (schemas/monitor.md): the latest frame a snippet obtained with
  /// frame(), downscaled to 320 px wide at most, as base64 JPEG; "" when none is new.
  std::string feed_message(long long t_ms) override;
  /// Forget which frame was sent: the next feed_message() sends the latest again.
  void feed_reset() override { feed_sent_ = -1; }

  using Clock = std::chrono::steady_clock;

  /// Live: the grabber's latest frame (lockstep: the one synced) for the instant.
  void read(CameraSnap& latest) override;
  /// The instant's frame: live, what read() took; fed, the script's file, read once.
  void snapshot_taken() override;
  /// The recording gets the frame of this instant, once (lossless PNG, base64).
  void record_frame() const;
  /// CRC-32 of a frame's pixels, row by row (zlib.crc32 of a numpy array's bytes).
  static std::uint32_t pixels_crc(const cv::Mat& m);

  struct Grabber;  // the grabber thread's state (src/hfsmc_camera.cpp)

  static bool parse_size(const std::string& text, int* w, int* h);
  static bool is_number(const std::string& s);
  static bool exists(const std::string& path);

  std::shared_ptr<Grabber> g_;
  simclock::Client* sim_ = nullptr;  // --clock sim: the frames the simulator names
  cv::Mat held_, held_jpeg_;  // lockstep: the frame synced for the coming instant
  long held_count_ = 0;
  long long held_us_ = 0;
  std::map<std::string, std::string> given_;  // the options as given (hfsmc.interfaces)
  cv::Mat snap_frame_;  // the snapshot's frame: the automaton's thread only
  cv::Mat snap_jpeg_, read_frame_, read_jpeg_;  // read_: what read() took
  mutable long recorded_ = 0;  // the number of the last frame recorded
  std::string loaded_;  // the file image_ holds
  cv::Mat image_;
  bool warned_ = false;  // said that a frame's pixels are not the recorded ones
  long feed_sent_ = -1;  // the number of the frame last sent (the monitor's thread only)
  std::thread thread_;
};

}  // namespace hfsmc
