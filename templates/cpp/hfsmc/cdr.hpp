// hfsmc: plain CDR (XCDR1) as ROS 2 puts its messages on the wire (docs/ros2-cpp.md).
//
// The generated message types (include/PKG/msg/NAME.hpp, made by hfsmc from the distro's
// definitions) write and read themselves with these two classes: a 4-byte encapsulation
// header (CDR_LE: 00 01 00 00), then each field aligned to its own size counted from the
// end of the header (8 for float64/int64, as rmw_cyclonedds and rosbags do), strings as a
// uint32 length that counts the terminating NUL, sequences as a uint32 count. Writing gives
// exactly rosbags' bytes (no trailing padding: the DDS layer adds it). Reading checks every
// length against what is left, so a malformed sample from the network throws
// cdr::Malformed (the runtime drops and counts it) and never reads past its end or
// allocates more than the sample could hold.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

namespace hfsmc {
namespace cdr {

/// A sample that does not parse as its type (short, a length past its end, no NUL).
struct Malformed : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// A bounded sequence (`float64[<=3]`): a std::vector whose bound is checked when the
/// message is written (std::length_error) and when one is read (Malformed).
template <class T, std::size_t N>
class BoundedVector : public std::vector<T> {
 public:
  using std::vector<T>::vector;
  static constexpr std::size_t bound = N;
};

class Writer {
 public:
  Writer() { buf_ = {0x00, 0x01, 0x00, 0x00}; }  // CDR_LE, options 0

  template <class T>
  void prim(T v) {
    static_assert(std::is_arithmetic<T>::value, "a primitive");
    align(sizeof(T));
    const auto* p = reinterpret_cast<const std::uint8_t*>(&v);
    buf_.insert(buf_.end(), p, p + sizeof(T));  // little-endian host (x86-64, arm64)
  }
  void boolean(bool v) { prim<std::uint8_t>(v ? 1 : 0); }
  void count(std::size_t n) {
    if (n > 0xffffffffu) throw std::length_error("hfsmc::cdr: sequence longer than 2^32-1");
    prim<std::uint32_t>(static_cast<std::uint32_t>(n));
  }
  void string(const std::string& s, std::size_t bound = 0) {
    if (bound && s.size() > bound)
      throw std::length_error("hfsmc::cdr: string longer than its bound " + std::to_string(bound));
    count(s.size() + 1);
    buf_.insert(buf_.end(), s.begin(), s.end());
    buf_.push_back(0);
  }
  template <class T>
  void prims(const T* data, std::size_t n) {  // an array of primitives, no count
    if (n == 0) return;
    align(sizeof(T));
    const auto* p = reinterpret_cast<const std::uint8_t*>(data);
    buf_.insert(buf_.end(), p, p + n * sizeof(T));
  }
  void bound(std::size_t n, std::size_t b) const {
    if (b && n > b)
      throw std::length_error("hfsmc::cdr: sequence longer than its bound " + std::to_string(b));
  }
  const std::vector<std::uint8_t>& bytes() const { return buf_; }
  std::vector<std::uint8_t>&& take() { return std::move(buf_); }

 private:
  void align(std::size_t a) {
    std::size_t off = buf_.size() - 4;
    buf_.resize(buf_.size() + ((a - off % a) % a), 0);
  }
  std::vector<std::uint8_t> buf_;
};

class Reader {
 public:
  /// `data` holds the encapsulation header; CDR_LE and CDR_BE are read, anything else
  /// (XCDR2, parameter lists) is Malformed.
  Reader(const std::uint8_t* data, std::size_t size) : p_(data), n_(size) {
    if (size < 4 || data[0] != 0x00 || (data[1] != 0x00 && data[1] != 0x01))
      throw Malformed("not a plain CDR sample (encapsulation header)");
    swap_ = data[1] == 0x00;
    pos_ = 4;
  }

  template <class T>
  T prim() {
    static_assert(std::is_arithmetic<T>::value, "a primitive");
    align(sizeof(T));
    need(sizeof(T));
    T v;
    std::memcpy(&v, p_ + pos_, sizeof(T));
    pos_ += sizeof(T);
    if (swap_) v = swapped(v);
    return v;
  }
  bool boolean() { return prim<std::uint8_t>() != 0; }
  /// A sequence's count, at most what the rest could hold with `min_size` bytes each.
  std::size_t count(std::size_t min_size) {
    std::size_t n = prim<std::uint32_t>();
    if (min_size == 0) min_size = 1;
    if (n > (n_ - pos_) / min_size) throw Malformed("a sequence longer than the sample");
    return n;
  }
  void string(std::string& s, std::size_t bound = 0) {
    std::size_t n = prim<std::uint32_t>();
    if (n == 0) throw Malformed("a string without its terminating NUL");
    need(n);
    if (p_[pos_ + n - 1] != 0) throw Malformed("a string without its terminating NUL");
    if (bound && n - 1 > bound) throw Malformed("a string longer than its bound");
    s.assign(reinterpret_cast<const char*>(p_ + pos_), n - 1);
    pos_ += n;
  }
  template <class T>
  void prims(T* data, std::size_t n) {
    if (n == 0) return;
    align(sizeof(T));
    need(n * sizeof(T));
    std::memcpy(data, p_ + pos_, n * sizeof(T));
    pos_ += n * sizeof(T);
    if (swap_)
      for (std::size_t i = 0; i < n; ++i) data[i] = swapped(data[i]);
  }
  void bound(std::size_t n, std::size_t b) const {
    if (b && n > b) throw Malformed("a sequence longer than its bound");
  }

 private:
  void align(std::size_t a) {
    std::size_t off = pos_ - 4;
    pos_ += (a - off % a) % a;
    if (pos_ > n_) throw Malformed("a sample shorter than its type");
  }
  void need(std::size_t k) const {
    if (k > n_ - pos_) throw Malformed("a sample shorter than its type");
  }
  template <class T>
  static T swapped(T v) {
    std::uint8_t b[sizeof(T)];
    std::memcpy(b, &v, sizeof(T));
    for (std::size_t i = 0; i < sizeof(T) / 2; ++i) std::swap(b[i], b[sizeof(T) - 1 - i]);
    std::memcpy(&v, b, sizeof(T));
    return v;
  }
  const std::uint8_t* p_;
  std::size_t n_;
  std::size_t pos_ = 0;
  bool swap_ = false;
};

/// The ROS 2 facts about a generated message type, specialised in its header.
template <class T>
struct Traits;

/// A message as CDR bytes, with the encapsulation header (rosbags' bytes exactly).
template <class T>
std::vector<std::uint8_t> serialize(const T& msg) {
  Writer w;
  cdr_write(w, msg);
  return w.take();
}

/// A message from CDR bytes; Malformed when they do not hold one.
template <class T>
T deserialize(const std::uint8_t* data, std::size_t size) {
  Reader r(data, size);
  T msg;
  cdr_read(r, msg);
  return msg;
}

}  // namespace cdr
}  // namespace hfsmc
