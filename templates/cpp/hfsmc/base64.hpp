// hfsmc/base64.hpp: base64 (RFC 4648, with padding) both ways, for the bytes a recording
// keeps as text: a camera's frames, a ROS 2 sample's, goal's or request's CDR.
// Copied into every C++ component (the runtime's headers).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace hfsmc {

inline std::string base64(const std::vector<std::uint8_t>& data) {
  static const char* const abc = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((data.size() + 2) / 3 * 4);
  std::size_t k = 0;
  for (; k + 2 < data.size(); k += 3) {
    const unsigned v = (data[k] << 16) | (data[k + 1] << 8) | data[k + 2];
    out += {abc[v >> 18], abc[(v >> 12) & 63], abc[(v >> 6) & 63], abc[v & 63]};
  }
  if (k + 1 == data.size()) {
    const unsigned v = data[k] << 16;
    out += {abc[v >> 18], abc[(v >> 12) & 63], '=', '='};
  } else if (k + 2 == data.size()) {
    const unsigned v = (data[k] << 16) | (data[k + 1] << 8);
    out += {abc[v >> 18], abc[(v >> 12) & 63], abc[(v >> 6) & 63], '='};
  }
  return out;
}

// Strict, as Python's b64decode(validate=True): the alphabet, padding only at the end, a
// length that is a multiple of 4. False when the text is not that.
inline bool unbase64(const std::string& text, std::vector<std::uint8_t>& out) {
  if (text.size() % 4 != 0) return false;
  out.clear();
  out.reserve(text.size() / 4 * 3);
  unsigned acc = 0;
  int bits = 0;
  std::size_t pad = 0;
  for (std::size_t k = 0; k < text.size(); ++k) {
    const char c = text[k];
    int v;
    if (c >= 'A' && c <= 'Z') v = c - 'A';
    else if (c >= 'a' && c <= 'z') v = c - 'a' + 26;
    else if (c >= '0' && c <= '9') v = c - '0' + 52;
    else if (c == '+') v = 62;
    else if (c == '/') v = 63;
    else if (c == '=' && k + 2 >= text.size()) v = -1;
    else return false;
    if (v < 0) {
      ++pad;
      continue;
    }
    if (pad > 0) return false;  // data after padding
    acc = (acc << 6) | static_cast<unsigned>(v);
    bits += 6;
    if (bits >= 8) {
      bits -= 8;
      out.push_back(static_cast<std::uint8_t>((acc >> bits) & 0xFF));
    }
  }
  return true;
}

}  // namespace hfsmc
