// hfsmc: raw CDR through Cyclone DDS 0.10 (docs/ros2-cpp.md), for src/hfsmc_ros2.cpp only.
//
// A sertype whose samples are CDR bytes, as rmw_cyclonedds' serdata does for serialized
// messages: the generated message types write and read their CDR themselves, Cyclone only
// carries the bytes. Writing pads a sample to a multiple of 4 bytes and says so in the
// encapsulation options (as Cyclone's own serdata does); reading gives the bytes back without
// that padding, with options 0, so they are the sender's serialization exactly.
#pragma once

#include <cstdint>
#include <vector>

#include <dds/dds.h>
#include <dds/ddsi/ddsi_sertype.h>

namespace hfsmc {
namespace ros2 {
namespace wire {

/// A sample: CDR bytes with their 4-byte encapsulation header.
struct Raw {
  std::vector<std::uint8_t> bytes;
};

/// A new sertype of raw CDR samples named `dds_type` (`geometry_msgs::msg::dds_::Twist_`),
/// keyless, XCDR1 only; dds_create_topic_sertype takes it over.
struct ddsi_sertype* make_sertype(const char* dds_type);

}  // namespace wire
}  // namespace ros2
}  // namespace hfsmc
