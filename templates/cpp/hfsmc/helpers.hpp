// hfsmc/helpers.hpp: helpers of snippets that need no engine (docs/model.md).
// Copied unchanged into every C++ component; standard library only.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>

namespace hfsmc {

// Roll, pitch and yaw (rad, static x-y-z axes, as ROS 1's tf gave them) of anything with
// x, y, z and w: a geometry_msgs::msg::Quaternion, an Eigen::Quaterniond (x() etc. are
// methods there: use q.coeffs() order x, y, z, w) ...
template <class Q>
std::array<double, 3> euler_from_quaternion(const Q& q) {
    const double x = q.x, y = q.y, z = q.z, w = q.w;
    return {std::atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y)),
            std::asin(std::clamp(2 * (w * y - z * x), -1.0, 1.0)),
            std::atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))};
}

// The heading (rad, counter-clockwise from x, -pi..pi) of a quaternion.
template <class Q>
double yaw_of(const Q& q) {
    return std::atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z));
}

}  // namespace hfsmc
