"""rclpy peer for the r2r interop tests (crates/ros/tests/interop.rs).

  peer.py sub PREFIX   subscribe to ContactState, PropertyComparison and ArmCommand, print the
                       first of each as one JSON line each (all fields, read through rclpy),
                       exit 0; 1 on timeout
  peer.py pub PREFIX   publish the fixture TactileLatent, GripperCommand, GripperStatus and
                       VisualObservation every 100 ms until killed or 60 s pass

rclpy is an independent implementation of the ROS client side: what it reads is what any ROS 2
node would read from our r2r publishers.
"""
import json
import sys
import time

import rclpy
from rclpy.node import Node
from builtin_interfaces.msg import Time
from unitac_msgs.msg import (ArmCommand, ContactState, GripperCommand, GripperStatus,
                             PropertyComparison, TactileLatent, VisualObservation)


def plain(v):
    """A ROS message (or field value) as plain JSON-able Python."""
    if hasattr(v, "get_fields_and_field_types"):
        return {k: plain(getattr(v, k)) for k in v.get_fields_and_field_types()}
    if hasattr(v, "tolist"):
        return v.tolist()
    if isinstance(v, (list, tuple)):
        return [plain(x) for x in v]
    return v


def sub(prefix):
    node = Node("unitac_peer_sub")
    got = {}
    node.create_subscription(ContactState, prefix + "/contact_state",
                             lambda m: got.setdefault("contact_state", plain(m)), 10)
    node.create_subscription(PropertyComparison, prefix + "/property_comparison",
                             lambda m: got.setdefault("property_comparison", plain(m)), 10)
    node.create_subscription(ArmCommand, prefix + "/arm_command",
                             lambda m: got.setdefault("arm_command", plain(m)), 10)
    deadline = time.monotonic() + 30
    while len(got) < 3 and time.monotonic() < deadline:
        rclpy.spin_once(node, timeout_sec=0.05)
    for k in sorted(got):
        print(json.dumps({"type": k, "msg": got[k]}), flush=True)
    return 0 if len(got) == 3 else 1


def pub(prefix):
    node = Node("unitac_peer_pub")
    p1 = node.create_publisher(TactileLatent, prefix + "/tactile_latent", 10)
    p2 = node.create_publisher(GripperCommand, prefix + "/gripper_command", 10)
    p3 = node.create_publisher(GripperStatus, prefix + "/gripper_status", 10)
    p4 = node.create_publisher(VisualObservation, prefix + "/visual_observation", 10)
    lat = TactileLatent()
    lat.header.stamp = Time(sec=1_700_000_003, nanosec=500)
    lat.header.frame_id = "gsmini_optical_frame"
    lat.source = TactileLatent.SOURCE_PREDICTED
    lat.sensor_id = "D00045"
    lat.shape = [2, 3]
    lat.data = [0.5, -1.25, 3.0e-8, 1.0e30, -0.0, 7.0]
    lat.model_id = "reference@1234abcd"
    lat.solver = "heun"
    lat.steps = 8
    lat.guidance = 1.5
    lat.elapsed_s = 0.00165
    lat.valid = True
    lat.guard_report = ""
    cmd = GripperCommand()
    cmd.header.stamp = Time(sec=1_700_000_004, nanosec=999_999_999)
    cmd.header.frame_id = "gripper_base"
    cmd.mode = GripperCommand.MODE_FORCE
    cmd.position_m = 0.042
    cmd.speed_m_s = 0.01
    cmd.force_n = 12.5
    cmd.reason = "grasp the smoother fabric (B)"
    gs = GripperStatus()
    gs.header.stamp = Time(sec=1_700_000_006, nanosec=7)
    gs.header.frame_id = "gripper_base"
    gs.opening_m = 0.0375
    gs.target_m = 0.03125
    gs.force_n = 6.5
    gs.current_a = float("nan")  # unknown
    gs.object_detected = True
    gs.activation = "active"
    gs.motion = "stopped"
    gs.fault = ""
    vis = VisualObservation()
    vis.header.stamp = Time(sec=1_700_000_007, nanosec=8)
    vis.header.frame_id = "camera_optical_frame"
    vis.names = ["cup_width_m", "cup_x_m"]
    vis.values = [0.0815, -0.125]
    deadline = time.monotonic() + 60
    try:
        while time.monotonic() < deadline:
            p1.publish(lat)
            p2.publish(cmd)
            p3.publish(gs)
            p4.publish(vis)
            rclpy.spin_once(node, timeout_sec=0.1)
    except KeyboardInterrupt:  # the test stops us with SIGINT
        pass
    return 0


def main():
    if len(sys.argv) != 3 or sys.argv[1] not in ("sub", "pub"):
        print(__doc__, file=sys.stderr)
        return 2
    rclpy.init()
    try:
        return sub(sys.argv[2]) if sys.argv[1] == "sub" else pub(sys.argv[2])
    finally:
        rclpy.try_shutdown()


if __name__ == "__main__":
    sys.exit(main())
