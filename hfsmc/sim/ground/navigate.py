"""The simulator's ``navigate_to_pose`` (nav2_msgs/action/NavigateToPose) and
``reset_odometry`` (std_srvs/srv/Trigger) of each robot (SPEC 6.1, docs/ros2.md).

A goal's pose is read in the robot's ``odom`` frame (the simulator has no map: ``map`` and
``odom`` coincide, and a goal in another frame is rejected). The robot turns on the spot
to face the goal, drives to it along the straight line (steering to stay on it), then
turns to the goal's heading; it succeeds within 5 cm and 0.05 rad. It aborts when it
touches something or makes no progress for 2 s (blocked). Feedback, five times a second,
carries the pose, the time since the goal began and the distance remaining. A new goal
replaces a running one (the old one aborted, as Nav2's navigator does on preemption); a
cancel stops the robot and ends the goal canceled. ``reset_odometry`` makes the robot's
current pose the odom frame's origin.
"""

from __future__ import annotations

import math
from typing import Any

from hfsmc.sim.ground.base import DiffDrive, Pose, _wrap

REACHED_M = 0.05
HEADING_RAD = 0.05
FACING_RAD = 0.15  # turn on the spot until the goal is within this of straight ahead
BLOCKED_S = 2.0
FEEDBACK_S = 0.2
FRAMES = ("", "odom", "map")


class Navigator:
    """One robot's goal, moved on at every step of the simulation."""

    def __init__(self, robot: DiffDrive, server: Any, action: Any) -> None:
        self.robot, self.server, self.action = robot, server, action
        self.goal: bytes | None = None
        self.target = Pose(0.0, 0.0, 0.0)
        self.started = 0.0
        self.best = math.inf
        self.best_t = 0.0
        self.fed = -math.inf
        self.canceled = False
        self.now = 0.0

    def on_goal(self, gid: bytes, goal: Any) -> bool:
        frame = str(goal.pose.header.frame_id).rsplit("/", 1)[-1]
        if frame not in FRAMES:
            return False
        if self.goal is not None:
            self.server.finish(self.goal, 6, self.action.Result())
        q = goal.pose.pose.orientation
        yaw = math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z))
        p = goal.pose.pose.position
        self.goal, self.target = gid, Pose(float(p.x), float(p.y), yaw)
        self.started = self.best_t = self.now
        self.best, self.fed, self.canceled = math.inf, -math.inf, False
        return True

    def on_cancel(self, gid: bytes) -> bool:
        if gid == self.goal:
            self.canceled = True
        return gid == self.goal

    def step(self, t: float) -> None:
        """Command the base toward the goal, and end the goal when it is done."""
        self.now = t
        if self.goal is None:
            return
        gid = self.goal
        if self.server.status_of(gid) == 1:
            self.server.execute(gid)
        pose, _, _ = self.robot.odometry()
        dx, dy = self.target.x - pose.x, self.target.y - pose.y
        dist = math.hypot(dx, dy)
        if self.canceled:
            return self._end(t, 5)
        if self.robot.contact is not None and dist > REACHED_M:
            return self._end(t, 6)
        if dist < self.best - 0.01 or dist <= REACHED_M:
            self.best, self.best_t = min(dist, self.best), t
        heading = _wrap(self.target.yaw - pose.yaw)
        if dist <= REACHED_M:
            if abs(heading) <= HEADING_RAD:
                return self._end(t, 4)
            self.robot.command(0.0, max(-1.5, min(1.5, 2.0 * heading)), t)
            self.best_t = t
        else:
            err = _wrap(math.atan2(dy, dx) - pose.yaw)
            if abs(err) > FACING_RAD:
                self.robot.command(0.0, max(-1.5, min(1.5, 2.5 * err)), t)
                self.best_t = t  # turning on the spot is progress
            else:
                self.robot.command(min(self.robot.limits.max_speed, 0.8 * dist + 0.05),
                                   2.5 * err, t)
            if t - self.best_t > BLOCKED_S:
                return self._end(t, 6)
        if t - self.fed >= FEEDBACK_S:
            self.fed = t
            self._feedback(t, pose, dist)

    def _feedback(self, t: float, pose: Pose, dist: float) -> None:
        fb = self.action.Feedback()
        fb.current_pose.header.frame_id = "odom"
        fb.current_pose.pose.position.x = pose.x
        fb.current_pose.pose.position.y = pose.y
        fb.current_pose.pose.orientation.z = math.sin(pose.yaw / 2)
        fb.current_pose.pose.orientation.w = math.cos(pose.yaw / 2)
        spent = max(0.0, t - self.started)
        fb.navigation_time.sec = int(spent)
        fb.navigation_time.nanosec = int((spent % 1) * 1e9)
        fb.distance_remaining = dist
        self.server.publish_feedback(self.goal, fb)

    def _end(self, t: float, status: int) -> None:
        self.robot.command(0.0, 0.0, t)
        if self.goal is not None:
            self.server.finish(self.goal, status, self.action.Result())
        self.goal = None


def reset_odometry(robot: DiffDrive, trigger: Any) -> Any:
    """A handler for std_srvs/Trigger: the odom frame starts again where the robot is."""

    def handler(_request: Any) -> Any:
        robot.start = Pose(robot.pose.x, robot.pose.y, robot.pose.yaw)
        return trigger.Response(success=True, message="odometry reset")

    return handler
