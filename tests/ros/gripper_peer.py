"""rclpy peer for the gripper node test (crates/ros/tests/gripper.rs).

  gripper_peer.py NS SECONDS
      wait for an active GripperStatus from NS/gripper_status; command a close
      (MODE_POSITION to 0 m, 0.05 m/s, 20 N) on NS/gripper_command until the status reports an
      object, then an open (to 0.08 m) until the fingers stop without one. Print one JSON object:
      {"first": status, "caught": status, "opened": status, "joints": [[position, effort, frame_id]
      of the joint_states received with caught and opened], "statuses": count}; exit 1 on timeout.
"""
import json
import math
import sys
import time

import rclpy
from rclpy.node import Node
from sensor_msgs.msg import JointState
from unitac_msgs.msg import GripperCommand, GripperStatus


def plain(m):
    """A GripperStatus as JSON-able values (NaN, an unknown, as null)."""
    def value(v):
        return None if isinstance(v, float) and math.isnan(v) else v
    return {k: value(getattr(m, k)) if k != "header" else {"frame_id": m.header.frame_id}
            for k in m.get_fields_and_field_types()}


def value_of(v):
    return None if math.isnan(v) else v


def main():
    ns, seconds = sys.argv[1], float(sys.argv[2])
    rclpy.init()
    try:
        node = Node("unitac_gripper_peer")
        last = {"status": None, "joint": None, "n": 0}

        def on_status(m):
            last["status"] = m
            last["n"] += 1

        def on_joint(m):
            last["joint"] = m

        node.create_subscription(GripperStatus, f"{ns}/gripper_status", on_status, 10)
        node.create_subscription(JointState, f"{ns}/joint_states", on_joint, 10)
        pub = node.create_publisher(GripperCommand, f"{ns}/gripper_command", 10)
        end = time.monotonic() + seconds
        out = {}

        def spin_until(done):
            while time.monotonic() < end:
                rclpy.spin_once(node, timeout_sec=0.02)
                if last["status"] is not None and done(last["status"]):
                    return True
            return False

        def command(position):
            c = GripperCommand()
            c.mode = GripperCommand.MODE_POSITION
            c.position_m, c.speed_m_s, c.force_n = position, 0.05, 20.0
            c.reason = "gripper node test"
            pub.publish(c)

        if not spin_until(lambda s: True):
            print(json.dumps({"error": "no gripper_status"}))
            return 1
        out["first"] = plain(last["status"])
        if not spin_until(lambda s: s.activation == "active"):
            print(json.dumps({"error": "never active", "first": out["first"]}))
            return 1
        joints = []
        for key, position, done in (("caught", 0.0, lambda s: s.object_detected),
                                    ("opened", 0.08,
                                     lambda s: not s.object_detected and s.motion == "reached")):
            sent = time.monotonic() - 1.0
            ok = False
            while time.monotonic() < end and not ok:
                if time.monotonic() - sent > 0.5:
                    command(position)
                    sent = time.monotonic()
                rclpy.spin_once(node, timeout_sec=0.02)
                ok = last["status"] is not None and done(last["status"])
            if not ok:
                print(json.dumps({"error": f"not {key}", "last": plain(last["status"])}))
                return 1
            out[key] = plain(last["status"])
            # The joint state of the same reading comes with it; spin a little to get it.
            t = time.monotonic() + 0.2
            while time.monotonic() < t:
                rclpy.spin_once(node, timeout_sec=0.02)
            j = last["joint"]
            joints.append([[value_of(x) for x in j.position], [value_of(x) for x in j.effort],
                           j.header.frame_id, list(j.name)])
        out["joints"] = joints
        out["statuses"] = last["n"]
        print(json.dumps(out))
        return 0
    finally:
        rclpy.try_shutdown()


if __name__ == "__main__":
    sys.exit(main())
